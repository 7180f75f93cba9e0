#pragma once
// The skin's lateral blur: skin spreads the contact pressure sideways before it blanches, as a
// Gaussian of σ about 0.3 mm (SKIN.md, forward model step 1). Three places use it, each as a plain
// value taken from here: the simulated skin (SkinParameters::blur_sigma_mm, the truth a render
// uses), the calibration's field fit (FieldFitOptions::skin_blur_mm, `calibrate-pressure
// --skin-blur-mm`, alias `--blur-mm`: the pressure under the indenter as the skin feels it, written
// into the calibration as `skin_blur_mm`) and the assessment's resolution term
// (BlanchingOptions::skin_blur_mm, `assess --skin-blur-mm`, scene key `assess.skin_blur_mm`: the
// signal reads the pressure blurred). An assessment takes the calibration's blur unless the scene
// or command line gives one, and warns when a given one differs (cli/assess_setup.cpp). This
// struct owns the default and the rule.
#include <cmath>
#include <string>

namespace clearfit {

struct SkinBlur {
  double sigma_mm = 0.3;  ///< Gaussian σ of the lateral spread, mm
  static constexpr double max_sigma_mm = 5;
  /// The rule, in words, for messages.
  static constexpr const char* rule = "the skin's lateral blur, a length in mm from 0 to 5 (SKIN.md: about 0.3)";
  bool valid() const { return std::isfinite(sigma_mm) && sigma_mm >= 0 && sigma_mm <= max_sigma_mm; }
  /// Throws std::invalid_argument "<name> = <value>: must be <rule>".
  void validate(const std::string& name) const;
};

}  // namespace clearfit
