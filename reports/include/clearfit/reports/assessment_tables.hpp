#pragma once
// Tables people paste, beside heatmap.glb (docs/assessment-outputs.md):
// hotspots.csv (one row per place), vertices.csv and heatmap.ply (every mesh
// vertex with its pressure, signal and whether the camera sees it).
#include <clearfit/fit/assessment.hpp>

#include <cstdint>
#include <filesystem>
#include <vector>

namespace clearfit {

/// 1 for a vertex of the contact chart whose signal is known (the camera sees it), else 0.
std::vector<std::uint8_t> vertex_seen(const Assessment& a, const Chart& chart);

/// hotspots.csv: one row per place (id as in report.json), its area at each threshold.
void write_hotspots_csv(const Assessment& a, const std::filesystem::path& path);

/// vertices.csv: vertex, x, y, z (mm), contact, seen, pressure_kpa, signal, pressure_sigma_kpa (empty where not seen;
/// σ empty also where the pressure is no estimate: below detection, saturated).
void write_vertex_csv(const Assessment& a, const Mesh& mesh, const Chart& chart, const std::filesystem::path& path);

/// heatmap.ply: binary PLY of the mesh with float pressure_kpa, float signal and uchar seen per vertex.
void write_vertex_ply(const Assessment& a, const Mesh& mesh, const Chart& chart, const std::filesystem::path& path);

}  // namespace clearfit
