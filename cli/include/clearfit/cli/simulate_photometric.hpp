#pragma once
// simulation.glare, simulation.exposure and simulation.flicker.drift_hz_per_s
// of the scene file (see simulate_photometric.cpp for the format).
#include <clearfit/cli/scene.hpp>

#include <clearfit/fit/simulate_photometric.hpp>

namespace clearfit::cli {

/// The photometric effects of a `simulation:` section: `defaults` (a preset's;
/// none by default) with each effect the section names replacing its default
/// (a glare list or a steps list replaces the whole list).
sim::PhotometricEffects parse_photometric(const SceneReader& reader, const YAML::Node& simulation, sim::PhotometricEffects defaults = {});

}  // namespace clearfit::cli
