#include <clearfit/fit/skin_blur.hpp>
#include <clearfit/format.hpp>

#include <stdexcept>

namespace clearfit {

void SkinBlur::validate(const std::string& name) const {
  if (!valid()) throw std::invalid_argument(name + " = " + significant_digits(sigma_mm, 4) + ": must be " + rule);
}

}  // namespace clearfit
