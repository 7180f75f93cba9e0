#pragma once
// The refraction map: for every camera pixel, the skin point it sees through
// the printed part (and why not, where it sees none).
//
// Per pixel (exact mode): unproject through the camera's mrcal lens model →
// ray in the part frame (part_from_cam) → first hit on the part → vector Snell
// refraction from the camera-side medium into the part (smooth or flat normal)
// → the next face the refracted ray meets. The pixel is valid when the ray
// entered through a non-contact face and the next face is a contact face; the
// skin point is that intersection. Every invalid pixel carries a reason.
#include <clearfit/camera/camera_model.hpp>
#include <clearfit/error.hpp>
#include <clearfit/geometry/chart.hpp>
#include <clearfit/geometry/contact.hpp>
#include <clearfit/geometry/ray_index.hpp>
#include <clearfit/refraction/optics.hpp>

#include <cstdint>
#include <limits>
#include <memory>
#include <type_traits>
#include <utility>
#include <string>
#include <vector>

namespace clearfit {

/// Why a pixel has (or lacks) a skin point. Values are stable: they are
/// written to files.
enum class PixelStatus : std::uint8_t {
  valid = 0,
  outside = 1,          ///< culled: the ray cannot reach the part (outside its image bound)
  miss = 2,             ///< the ray misses the part
  no_ray = 3,           ///< the lens model cannot unproject this pixel
  contact_first = 4,    ///< the first face hit is a contact face (skin seen from the camera side, not through the part)
  back_face = 5,        ///< the first hit is a face seen from inside (camera inside the part, or a flipped mesh)
  entry_tir = 6,        ///< total internal reflection at entry (camera-side medium denser than the part)
  exits_elsewhere = 7,  ///< the refracted ray meets a non-contact face (or nothing) before the skin
  contact_tir = 8,      ///< reaches the contact face beyond the part→skin critical angle: sees a reflection
};
constexpr int kPixelStatusCount = 9;
const char* to_string(PixelStatus status);

struct MapOptions {
  optics::Indices indices;               ///< n_medium (camera side), n_part, n_skin
  enum class Normals { smooth, flat } normals = Normals::smooth;
  /// exact: every pixel traced. grid: cells of grid_step px with nine traced
  /// nodes (corners, edge midpoints, centre); cells whose nodes are all valid
  /// on one contact component are filled by quadratic interpolation, others
  /// split. adaptive: like grid, but a cell is filled only if eight exactly
  /// traced check pixels (its quadrants' centres, at 1/4 and 3/4 of both
  /// diagonals, and one pixel drawn inside each quadrant: the centres alone
  /// missed the ripple facets leave in the map) are within half of tolerance_um
  /// of the interpolation, and its parent's nodes and checks were all valid
  /// with an error of at most 16 tolerances (with flat normals, all entered
  /// the part through one face); otherwise it is split (quadtree; the checks
  /// and their thresholds: refraction/src/quadtree.hpp).
  /// In both, a cell of 8 px or less that a validity boundary (or a change of
  /// contact component) crosses goes to the boundary resolver: the pixels on
  /// both sides of every change of validity the nodes reveal are traced (a
  /// valid sliver narrower than the node spacing can be missed), and the valid pixels behind them are filled from
  /// a least-squares quadratic through the traced valid pixels around the cell
  /// where it fits all of them within tolerance_um (traced otherwise). Where
  /// two invalid reasons meet, the pixels take their nearest node's reason
  /// (nodes are 4 px apart there) unless exact_reasons.
  enum class Mode { exact, grid, adaptive } mode = Mode::exact;
  int grid_step = 32;                    ///< starting cell size, pixels (power of two, 2..256)
  double tolerance_um = 1.0;             ///< adaptive: accepted interpolation error on the skin, µm
  /// grid/adaptive: trace both sides of boundaries between two invalid
  /// reasons too (the reason image then equals the exact trace's; slower).
  bool exact_reasons = false;
  bool fast_paths = true;                ///< straight rays when n_medium == n_part; closed form for a flat slab
  bool cull = true;                      ///< trace only pixels inside the part's projected bound
  /// Throws std::invalid_argument naming the field, its value and the rule.
  void validate() const;
};

/// A part ready to be traced: mesh, contact surface, ray index (with the corner
/// normals used for smooth shading) and optionally the contact chart.
struct TraceScene {
  const Mesh* mesh = nullptr;
  const ContactSurface* contact = nullptr;
  const RayIndex* index = nullptr;
  const Chart* chart = nullptr;  ///< optional: fills chart_uv
};

struct MapStats {
  long long pixels = 0, traced = 0;
  long long by_status[kPixelStatusCount] = {};
  long long interpolated = 0;            ///< valid pixels filled by interpolation (grid/adaptive)
  double coverage = 0;                   ///< valid / pixels
  std::string fast_path = "none";        ///< "none" | "index-matched" | "flat-slab" | both joined by '+'
  std::string mode = "exact";
  /// unproject: the lens model's pixel -> ray for the traced pixels not
  /// unprojected before for this camera in this process (cached per camera);
  /// trace: everything else of the tracing.
  double unproject_ms = 0, cull_ms = 0, trace_ms = 0, total_ms = 0;
  /// Estimated error of the approximation: the largest difference between an
  /// exactly traced cell centre and the interpolation, over accepted cells
  /// (adaptive), or over every cell (grid). 0 for the exact trace.
  double max_error_um = 0;
};

/// Allocator whose resize() leaves trivially constructible elements
/// uninitialised: a map writes every pixel once, and zero-filling 100 MB
/// before that costs more than some maps take.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <class U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
/// One per-pixel array of a map (a std::vector; resize() does not zero).
template <class T>
using PixelArray = std::vector<T, DefaultInitAllocator<T>>;

/// Dense per-pixel results, row-major (pixel (x, y) at y * width + x; pixel
/// (0,0) is the centre of the top-left pixel, as in mrcal).
struct RefractionMap {
  int width = 0, height = 0;
  PixelArray<PixelStatus> status;
  PixelArray<Vec3> skin_point;              ///< part frame, mm (double); NaN unless valid
  PixelArray<std::int32_t> face;            ///< contact face index (mesh), -1 unless valid
  PixelArray<Eigen::Vector2f> bary;         ///< weights of corners 1 and 2 (corner 0 = 1 − both)
  PixelArray<Eigen::Vector2f> chart_uv;     ///< chart mm; NaN unless valid and a chart was given
  PixelArray<float> incidence_deg;          ///< angle of incidence at entry
  PixelArray<float> contact_deg;            ///< angle of the refracted ray to the contact face normal
  PixelArray<float> transmittance;          ///< Fresnel T entry × T contact (unpolarised)
  /// The share of the pixel's footprint (4 × 4 rays over its square) that sees the skin: the outline of
  /// the seen region at sub-pixel precision (a status alone places a straight edge only to ±0.5 px).
  /// 0 or 1 away from the outline; empty when the map was made without it (then read the status).
  PixelArray<float> seen_fraction;
  MapStats stats;

  std::size_t index(int x, int y) const { return static_cast<std::size_t>(y) * width + x; }
  /// seen_fraction at pixel index k, or 1 / 0 from the status when the map has none.
  float seen_share(std::size_t k) const {
    return seen_fraction.empty() ? (status[k] == PixelStatus::valid ? 1.f : 0.f) : seen_fraction[k];
  }
};

/// One traced ray (the per-pixel result, also for callers with their own rays).
struct SkinSample {
  PixelStatus status = PixelStatus::miss;
  Vec3 skin_point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  int face = -1;
  std::array<double, 3> bary{};
  Vec3 entry_point = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  int entry_face = -1;
  Vec3 entry_normal = Vec3::Zero();       ///< unit normal used for refraction at entry (outward)
  Vec3 refracted_dir = Vec3::Zero();      ///< unit, inside the part
  double incidence_deg = std::numeric_limits<double>::quiet_NaN();
  double contact_deg = std::numeric_limits<double>::quiet_NaN();
  double transmittance = 0;
};

/// Traces one ray (origin and direction in the part frame) through the part.
/// Same rules as compute_refraction_map's exact mode.
SkinSample trace_skin_ray(const TraceScene& scene, const Vec3& origin, const Vec3& direction,
                          const MapOptions& options = {});
/// The same for a batch of rays (two batched casts; parallel). Only the rays'
/// origin and direction are used. out.size() must equal rays.size().
void trace_skin_rays(const TraceScene& scene, std::span<const Ray> rays, std::span<SkinSample> out,
                     const MapOptions& options = {});

/// An InputError about the pose (`cam_from_part`) rather than the part or the
/// camera: the map cannot be traced where the pose puts the part. Its file is
/// empty; a caller that knows where the pose came from names that file
/// (catching it by type, not by its message).
class PoseError : public InputError {
 public:
  using InputError::InputError;
};

/// Traces every pixel of `camera` (its imager size), with `cam_from_part`
/// placing the part. Throws std::invalid_argument on bad options, InputError
/// when the scene cannot be traced (no contact faces), PoseError when the pose
/// puts the whole part behind the camera. Parallel (TBB).
RefractionMap compute_refraction_map(const TraceScene& scene, const CameraModel& camera,
                                     const Rigid3& cam_from_part, const MapOptions& options = {});

/// The pixels whose seen_fraction compute_refraction_map measures with rays:
/// those whose 8 neighbours (inside the image) do not all share their
/// seen-or-not (status valid), row-major.
std::vector<std::uint32_t> seen_outline(const RefractionMap& map);
/// Rays per side of an outline pixel's square for its seen fraction.
constexpr int kSeenSub = 4;
/// The points (pixel coordinates) whose rays measure the seen fraction of
/// pixel (x, y): kSeenSub x kSeenSub over its square, row-major.
std::array<Vec2, kSeenSub * kSeenSub> seen_sample_points(int x, int y);

/// The map's skin points as a NumPy .npy file: float32, shape (H, W, 3), NaN
/// where invalid. Written atomically.
void write_skin_points_npy(const RefractionMap& map, const std::filesystem::path& path);

}  // namespace clearfit
