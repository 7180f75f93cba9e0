// mrcal's optimizer behind mrcal_optimize_api.hpp: problem marshalling, the
// solve, and a finite-difference Jacobian of mrcal's residuals (the C API
// gives the analytic one only as a cholmod_sparse, whose headers Debian ships
// in libsuitesparse-dev; central differences of mrcal_optimizer_callback are
// accurate enough for uncertainty propagation).
#include "mrcal_api.hpp"
#include "mrcal_optimize_api.hpp"
#include "stderr_capture.hpp"

#include <cstring>
#include <stdexcept>

namespace clearfit::detail {
namespace {

// Everything mrcal's optimizer entry points take besides the state.
struct Marshalled {
  Lens lens;
  std::vector<mrcal_pose_t> frames;
  std::vector<mrcal_observation_board_t> observations;
  std::vector<mrcal_point3_t> pool;
  mrcal_calobject_warp_t warp{};
  int imagersize[2]{};
  mrcal_problem_selections_t selections{};
  mrcal_problem_constants_t constants{};
  int n_states = 0, n_measurements = 0;
};

Marshalled marshal(const BoardProblem& p, const Selection& s) {
  Marshalled m;
  m.lens = lens_or_throw(p.lensmodel);
  if (static_cast<int>(p.intrinsics.size()) != m.lens.num_params)
    throw std::invalid_argument("clearfit calibrate: intrinsics count does not match " + p.lensmodel);
  const int nf = static_cast<int>(p.frames.size());
  const std::size_t per_view = static_cast<std::size_t>(p.grid_width) * p.grid_height;
  if (p.corners.size() != per_view * p.frames.size())
    throw std::invalid_argument("clearfit calibrate: corner pool does not match frames x grid");
  m.frames.resize(nf);
  m.observations.resize(nf);
  for (int i = 0; i < nf; ++i) {
    std::memcpy(&m.frames[i], p.frames[i].data(), sizeof(double) * 6);
    m.observations[i].icam.intrinsics = 0;
    m.observations[i].icam.extrinsics = -1;
    m.observations[i].iframe = i;
  }
  m.pool.resize(p.corners.size());
  if (!(p.weight_scale > 0)) throw std::invalid_argument("clearfit calibrate: weight_scale must be positive");
  for (std::size_t i = 0; i < p.corners.size(); ++i) {
    for (int k = 0; k < 3; ++k) m.pool[i].xyz[k] = p.corners[i][k];
    if (m.pool[i].z > 0) m.pool[i].z *= p.weight_scale;
  }
  m.warp.x2 = p.warp[0];
  m.warp.y2 = p.warp[1];
  m.imagersize[0] = p.imager_width;
  m.imagersize[1] = p.imager_height;
  m.selections.do_optimize_intrinsics_core = s.core;
  m.selections.do_optimize_intrinsics_distortions = s.distortions;
  m.selections.do_optimize_extrinsics = false;
  m.selections.do_optimize_frames = s.frames;
  m.selections.do_optimize_calobject_warp = s.warp;
  m.selections.do_apply_regularization = s.regularization;
  m.selections.do_apply_outlier_rejection = s.outlier_rejection;
  m.constants.point_min_range = 1.0;
  m.constants.point_max_range = 1e6;
  m.n_states = mrcal_num_states(1, 0, nf, 0, 0, nf, m.selections, &m.lens.model);
  m.n_measurements =
      mrcal_num_measurements(nf, 0, p.grid_width, p.grid_height, 1, 0, nf, 0, 0, m.selections, &m.lens.model);
  return m;
}

/// The board measurements of x, in pixels (mrcal's are times the weight scale).
std::vector<double> board_part(const std::vector<double>& x, const BoardProblem& p) {
  const int n = mrcal_num_measurements_boards(static_cast<int>(p.frames.size()), p.grid_width, p.grid_height);
  std::vector<double> out(x.begin(), x.begin() + n);
  for (double& v : out) v /= p.weight_scale;
  return out;
}

}  // namespace

SolveOutput optimize(BoardProblem& p, const Selection& s) {
  Marshalled m = marshal(p, s);
  std::vector<double> x(static_cast<std::size_t>(m.n_measurements));
  const int nf = static_cast<int>(p.frames.size());
  mrcal_stats_t stats{};
  const std::string said = capture_stderr([&] {
    stats = mrcal_optimize(nullptr, 0, x.data(), static_cast<int>(x.size() * sizeof(double)), p.intrinsics.data(),
                           nullptr, m.frames.data(), nullptr, &m.warp, 1, 0, nf, 0, 0, m.observations.data(),
                           nullptr, nf, 0, m.pool.data(), &m.lens.model, m.imagersize, m.selections, &m.constants,
                           p.spacing_mm, p.grid_width, p.grid_height, false, false);
  });
  SolveOutput out;
  // mrcal's loop of outlier rejection says "Threw out some outliers (have a total of N now); going again"
  // at each pass: its count is stats.Noutliers. Anything else it says is kept for the caller.
  for (std::string& line : mrcal_messages(said))
    if (line.rfind("Threw out some outliers", 0) == 0) ++out.outlier_passes;
    else out.messages.push_back(std::move(line));
  out.ok = stats.rms_reproj_error__pixels >= 0;
  if (!out.ok) return out;
  out.rms_px = stats.rms_reproj_error__pixels / p.weight_scale;
  out.outliers = stats.Noutliers;
  for (int i = 0; i < nf; ++i) std::memcpy(p.frames[i].data(), &m.frames[i], sizeof(double) * 6);
  for (std::size_t i = 0; i < p.corners.size(); ++i)
    if (m.pool[i].z < 0) p.corners[i].z() = m.pool[i].z;  // inliers keep their given weight
  if (s.warp) p.warp = {m.warp.x2, m.warp.y2};
  out.board_residuals = board_part(x, p);
  return out;
}

PackedJacobian packed_jacobian(const BoardProblem& p, const Selection& s) {
  Marshalled m = marshal(p, s);
  const int nf = static_cast<int>(p.frames.size());
  PackedJacobian out;
  // scale: packing divides by it, so packing ones gives 1/scale.
  std::vector<double> ones(static_cast<std::size_t>(m.n_states), 1.0);
  mrcal_pack_solver_state_vector(ones.data(), 1, 0, nf, 0, 0, m.selections, &m.lens.model);
  out.scale.resize(m.n_states);
  for (int k = 0; k < m.n_states; ++k) out.scale[k] = 1.0 / ones[k];

  std::vector<double> intrinsics = p.intrinsics;
  // The address of every state element in our own copies.
  std::vector<double*> state(static_cast<std::size_t>(m.n_states), nullptr);
  out.istate_intrinsics = mrcal_state_index_intrinsics(0, 1, 0, nf, 0, 0, nf, m.selections, &m.lens.model);
  out.istate_frames = mrcal_state_index_frames(0, 1, 0, nf, 0, 0, nf, m.selections, &m.lens.model);
  const int n_intr = mrcal_num_states_intrinsics(1, m.selections, &m.lens.model);
  const int first_intr = s.core ? 0 : 4;  // models with a core; without one both index from 0
  const bool has_core = mrcal_lensmodel_metadata(&m.lens.model).has_core;
  for (int k = 0; k < n_intr; ++k)
    state[out.istate_intrinsics + k] = &intrinsics[(has_core ? first_intr : 0) + k];
  if (s.frames)
    for (int i = 0; i < nf; ++i)
      for (int k = 0; k < 6; ++k) state[out.istate_frames + 6 * i + k] = &m.frames[i].r.xyz[0] + k;
  if (s.warp) {
    const int iw = mrcal_state_index_calobject_warp(1, 0, nf, 0, 0, nf, m.selections, &m.lens.model);
    state[iw] = &m.warp.x2;
    state[iw + 1] = &m.warp.y2;
  }
  for (double* d : state)
    if (!d) throw std::logic_error("clearfit calibrate: unmapped mrcal state element");

  std::vector<double> b(static_cast<std::size_t>(m.n_states)), x(static_cast<std::size_t>(m.n_measurements));
  auto evaluate = [&](std::vector<double>& xo) {
    if (!mrcal_optimizer_callback(b.data(), static_cast<int>(b.size() * sizeof(double)), xo.data(),
                                  static_cast<int>(xo.size() * sizeof(double)), nullptr, intrinsics.data(),
                                  nullptr, m.frames.data(), nullptr, &m.warp, 1, 0, nf, 0, 0,
                                  m.observations.data(), nullptr, nf, 0, m.pool.data(), &m.lens.model,
                                  m.imagersize, m.selections, &m.constants, p.spacing_mm, p.grid_width,
                                  p.grid_height, false))
      throw std::runtime_error("clearfit calibrate: mrcal_optimizer_callback failed");
  };
  evaluate(x);
  out.n_board_measurements = mrcal_num_measurements_boards(nf, p.grid_width, p.grid_height);
  out.board_residuals = board_part(x, p);
  out.J.resize(m.n_measurements, m.n_states);
  std::vector<double> xp(x.size()), xm(x.size());
  constexpr double h = 1e-6;  // packed units are O(1)
  for (int k = 0; k < m.n_states; ++k) {
    double* v = state[k];
    const double v0 = *v, step = h * out.scale[k];
    *v = v0 + step;
    evaluate(xp);
    *v = v0 - step;
    evaluate(xm);
    *v = v0;
    for (int r = 0; r < m.n_measurements; ++r) out.J(r, k) = (xp[r] - xm[r]) / (2 * h * p.weight_scale);
  }
  return out;
}

}  // namespace clearfit::detail
