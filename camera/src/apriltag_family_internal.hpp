#pragma once
// AprilTag families by name, owned by a small RAII handle. Private to camera/src.
#include <apriltag/apriltag.h>

#include <memory>
#include <string>
#include <vector>

namespace clearfit::detail {

struct FamilyDeleter {
  void (*destroy)(apriltag_family_t*) = nullptr;
  void operator()(apriltag_family_t* f) const {
    if (f && destroy) destroy(f);
  }
};
using FamilyPtr = std::unique_ptr<apriltag_family_t, FamilyDeleter>;

/// Creates the family `name` (tag16h5 ... tagStandard52h13); nullptr if unknown.
FamilyPtr create_family(const std::string& name);
/// Every family name the library has.
const std::vector<std::string>& family_names();
/// True for families whose detected square is the outer black border with a
/// one-cell white border around it (tag16h5, tag25h9, tag36h10, tag36h11).
bool family_has_classic_border(const apriltag_family_t& family);

}  // namespace clearfit::detail
