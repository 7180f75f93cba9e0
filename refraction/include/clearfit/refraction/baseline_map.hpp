#pragma once
// The not-worn (baseline) capture's own refraction map. A real baseline is
// filmed with the part held just off the skin, or without the part, so its
// rays meet the skin elsewhere than the worn capture's rays do:
//  - held: the camera ray enters the part and reaches its contact surface as
//    in the worn map, leaves it into the gap (the camera-side medium: air, or
//    the oil of an immersion set-up; Snell and Fresnel part → medium, total
//    internal reflection there is contact_tir) and meets the skin `gap_mm`
//    further on;
//  - absent: the camera ray goes straight to the skin (no part);
//  - touching: the worn map itself (the skin on the contact surface).
// The skin is the contact surface moved `gap_mm` along its vertex normals
// (angle-weighted over the contact faces, outward: towards the skin), the
// same faces and barycentrics, so a skin point has the chart uv of the
// contact point it lies in front of (the skin point it touches when worn).
// The exit rays (first two casts) do not depend on the gap: BaselineRays
// traces them once, and map(gap) casts them onto the skin at each gap (one
// cast per pixel), which is what a search over the gap needs.
#include <clearfit/refraction/map.hpp>

#include <memory>
#include <span>
#include <string>
#include <vector>

namespace clearfit {

enum class BaselinePart { held, absent, touching };
const char* to_string(BaselinePart part);

/// The contact surface moved `gap_mm` along its vertex normals (outward), as
/// a mesh of the contact faces alone whose winding is reversed (its normals
/// point at the part: out of the body), with its ray index. Face k of `mesh`
/// is contact face `part_face[k]` of the part; its corner 1 and 2 are the
/// part face's corners 2 and 1. Throws std::invalid_argument for a negative or
/// non-finite gap.
struct SkinSurface {
  Mesh mesh;
  std::vector<int> part_face;
  std::unique_ptr<RayIndex> index;
  static SkinSurface offset(const Mesh& part, const ContactSurface& contact, double gap_mm);
};

/// The rays of the not-worn capture where they leave the part (held) or the
/// camera (absent), traced once; map(gap) meets them with the skin.
class BaselineRays {
 public:
  /// `worn`: the worn map of the same scene, camera and pose (its statuses
  /// say which pixels can reach the contact surface: held traces again those
  /// valid or contact_tir in it, absent casts every pixel inside the part's
  /// image bound). `options`: the worn map's (indices, normals). Throws
  /// std::invalid_argument for part = touching or a worn map of another size.
  BaselineRays(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part, const MapOptions& options,
               BaselinePart part, const RefractionMap& worn);
  ~BaselineRays();
  /// The baseline's map with the skin `gap_mm` (>= 0) beyond the contact
  /// surface: per pixel the skin point (on the moved skin, part frame), the
  /// contact face and barycentrics it lies in front of, its chart uv (when the
  /// scene has a chart), the incidence at entry, the angle at the part → gap
  /// interface (held) or at the skin (absent), the Fresnel transmittance of
  /// every interface including gap → skin. Pixels whose ray misses the moved
  /// skin, or meets it from behind, are exits_elsewhere (held) or miss
  /// (absent); the others keep the worn map's reason.
  RefractionMap map(double gap_mm) const;
  /// The chart uv (mm) where exit rays `which` (indices into pixels()) meet
  /// the skin at `gap_mm`, NaN where map() would not be valid: what a search
  /// over the gap needs, without a whole map per gap. Needs the scene's chart.
  std::vector<Vec2> chart_uv(double gap_mm, std::span<const std::uint32_t> which) const;
  BaselinePart part() const { return part_; }
  /// The pixels (index y · width + x) with an exit ray: the only ones map() can make valid.
  const std::vector<std::uint32_t>& pixels() const { return pixel_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  /// Where one exit ray meets the skin.
  struct Landing {
    PixelStatus status = PixelStatus::miss;
    int face = -1;
    std::array<double, 3> bary{};
    Vec3 point = Vec3::Zero();
    double contact_deg = 0, transmittance = 0;
  };
  /// Lands exit rays `which` (indices into pixels()) on the skin `gap_mm` beyond the contact surface.
  std::vector<Landing> land(double gap_mm, std::span<const std::uint32_t> which) const;

  const TraceScene scene_;
  BaselinePart part_;
  optics::Indices n_;
  int width_ = 0, height_ = 0;
  std::vector<PixelStatus> worn_status_;
  std::vector<std::uint32_t> pixel_;   ///< pixel index of each exit ray
  std::vector<Ray> exit_;              ///< origin on the contact surface (held) or the camera centre (absent), unit direction
  std::vector<SkinSample> at_contact_; ///< held: the trace to the contact surface (face, bary, angles, transmittance)
  std::vector<float> incidence_deg_;
};

/// The baseline's map for `part` at `gap_mm`: the worn map for touching, else
/// BaselineRays(...).map(gap_mm).
RefractionMap compute_baseline_map(const TraceScene& scene, const CameraModel& camera, const Rigid3& cam_from_part,
                                   const MapOptions& options, BaselinePart part, double gap_mm, const RefractionMap& worn);

}  // namespace clearfit
