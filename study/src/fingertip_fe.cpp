// The layered punch model on GetFEM (the only translation unit that includes it).
#include <clearfit/study/fingertip_fe.hpp>

#include <getfem/getfem_generic_assembly.h>
#include <getfem/getfem_interpolation.h>
#include <getfem/getfem_mesh_fem.h>
#include <getfem/getfem_mesh_im.h>
#include <getfem/getfem_model_solvers.h>
#include <getfem/getfem_models.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <regex>
#include <stdexcept>

namespace clearfit::study {
namespace {

enum Region : getfem::size_type { kAxis = 1, kTop = 2, kPunch = 3, kBottom = 4, kRim = 5 };

/// Node positions on [0, end]: step h up to `fine`, then growing by 1.25 per element; `keep` are forced nodes.
std::vector<double> axis_nodes(double fine, double end, double h, std::vector<double> keep) {
  std::vector<double> x;
  for (double v = 0, step = h; v < end - 1e-9; v += step) {
    x.push_back(v);
    if (v + step > fine + 1e-9) step *= 1.25;
  }
  x.push_back(end);
  for (double k : keep) {
    if (k <= 0 || k >= end) continue;
    auto it = std::lower_bound(x.begin(), x.end(), k);
    const double gap = *it - *(it - 1);
    if (*it - k < 1e-9 || k - *(it - 1) < 1e-9) continue;
    if (*it - k < 0.3 * gap && it + 1 != x.end()) *it = k;      // move the near node onto it
    else if (k - *(it - 1) < 0.3 * gap && it - 1 != x.begin()) *(it - 1) = k;
    else x.insert(it, k);
  }
  return x;
}

struct Layered {
  getfem::mesh mesh;
  std::vector<double> lambda, mu;  ///< per convex, kPa
};

/// The mesh, with the top faces inside `loaded_radius` in region kPunch (the punch face or the loaded disc).
Layered build_mesh(const PunchFeOptions& o, double loaded_radius) {
  std::vector<double> interfaces{0};
  for (const TissueLayer& l : o.layers) interfaces.push_back(interfaces.back() + l.thickness_mm);
  const double total = interfaces.back();
  const auto r = axis_nodes(o.roi_radius_mm, o.domain_radius_mm, o.element_mm, {loaded_radius});
  const auto d = axis_nodes(o.roi_depth_mm, total, o.element_mm, interfaces);
  Layered out;
  for (std::size_t j = 0; j + 1 < d.size(); ++j) {
    const double mid = 0.5 * (d[j] + d[j + 1]);
    const std::size_t layer = std::upper_bound(interfaces.begin(), interfaces.end(), mid) - interfaces.begin() - 1;
    const TissueLayer& t = o.layers[std::min(layer, o.layers.size() - 1)];
    const double lam = t.youngs_kpa * t.poisson / ((1 + t.poisson) * (1 - 2 * t.poisson));
    const double mu = t.youngs_kpa / (2 * (1 + t.poisson));
    for (std::size_t i = 0; i + 1 < r.size(); ++i) {
      const bgeot::base_node a{r[i], -d[j]}, b{r[i + 1], -d[j]}, c{r[i + 1], -d[j + 1]}, e{r[i], -d[j + 1]};
      for (const auto& tri : {std::array{a, b, c}, std::array{a, c, e}}) {
        const auto cv = out.mesh.add_triangle_by_points(tri[0], tri[1], tri[2]);
        if (out.lambda.size() <= cv) out.lambda.resize(cv + 1), out.mu.resize(cv + 1);
        out.lambda[cv] = lam;
        out.mu[cv] = mu;
      }
    }
  }
  getfem::mesh_region border;
  getfem::outer_faces_of_mesh(out.mesh, border);
  for (getfem::mr_visitor f(border); !f.finished(); ++f) {
    const auto n = out.mesh.normal_of_face_of_convex(f.cv(), f.f());
    const auto pts = out.mesh.points_of_face_of_convex(f.cv(), f.f());
    const double rc = 0.5 * (pts[0][0] + pts[1][0]);
    if (n[0] < -0.5) out.mesh.region(kAxis).add(f.cv(), f.f());
    else if (n[0] > 0.5) out.mesh.region(kRim).add(f.cv(), f.f());
    else if (n[1] < -0.5) out.mesh.region(kBottom).add(f.cv(), f.f());
    else out.mesh.region(rc < loaded_radius ? kPunch : kTop).add(f.cv(), f.f());
  }
  return out;
}

// Strain with the hoop term, the stress, von Mises, the energy density (per radian: times X(1)).
const std::string kStrain =
    "Def err := Grad_u(1,1); Def ezz := Grad_u(2,2); Def erz := 0.5*(Grad_u(1,2)+Grad_u(2,1)); Def ett := u(1)/X(1);"
    "Def tr := err+ezz+ett;";
const std::string kStress =
    "Def srr := Lam*tr+2*Mu*err; Def szz := Lam*tr+2*Mu*ezz; Def stt := Lam*tr+2*Mu*ett; Def srz := 2*Mu*erz;";

PunchStress solve(const PunchFeOptions& o, double load_radius_mm, double pressure_kpa) {
  o.validate();
  gmm::set_traces_level(0);  // GetFEM's assembly traces are not the user's business
  const bool punch = load_radius_mm <= 0;
  Layered layered = build_mesh(o, punch ? o.punch_radius_mm : load_radius_mm);
  getfem::mesh& m = layered.mesh;
  getfem::mesh_fem mf_u(m, 2), mf_p0(m);
  mf_u.set_classical_finite_element(2);
  mf_p0.set_classical_discontinuous_finite_element(0);
  getfem::mesh_im mim(m);
  mim.set_integration_method(m.convex_index(), getfem::int_method_descriptor("IM_TRIANGLE(6)"));
  getfem::model md;
  md.add_fem_variable("u", mf_u);
  std::vector<double> lam(mf_p0.nb_dof()), mu(mf_p0.nb_dof());
  for (dal::bv_visitor cv(m.convex_index()); !cv.finished(); ++cv) {
    const auto dof = mf_p0.ind_basic_dof_of_element(cv)[0];
    lam[dof] = layered.lambda[cv];
    mu[dof] = layered.mu[cv];
  }
  md.add_initialized_fem_data("Lam", mf_p0, lam);
  md.add_initialized_fem_data("Mu", mf_p0, mu);
  getfem::add_linear_term(md, mim, kStrain + "(Lam*tr*(Div_Test_u+Test_u(1)/X(1)) + 2*Mu*(Sym(Grad_u):Grad_Test_u + ett*Test_u(1)/X(1)))*X(1)",
                          getfem::size_type(-1), true, true);
  getfem::add_Dirichlet_condition_with_multipliers(md, mim, "u", 1, kBottom);
  getfem::add_normal_Dirichlet_condition_with_multipliers(md, mim, "u", 1, kAxis);
  if (punch) {
    md.add_initialized_scalar_data("depth", -o.depth_mm);
    getfem::add_normal_Dirichlet_condition_with_multipliers(md, mim, "u", 1, kPunch, "depth");
  } else {  // a uniform pressure on the disc, pushing down
    getfem::add_source_term(md, mim, "-" + std::to_string(pressure_kpa) + "*Test_u(2)*X(1)", kPunch);
  }
  gmm::iteration iter(1e-10, 0, 40000);
  getfem::standard_solve(md, iter);
  if (!iter.converged()) throw std::runtime_error("the punch model's solver did not converge");

  PunchStress s;
  s.elements = static_cast<int>(m.nb_convex());
  s.dofs = static_cast<int>(mf_u.nb_dof());
  getfem::ga_workspace energy(md);
  energy.add_expression(kStrain + kStress + "0.5*(srr*err+szz*ezz+stt*ett+2*srz*erz)*X(1)*2*pi", mim);
  energy.assembly(0);
  const double u = energy.assembled_potential();  // kPa·mm³ = 1e-3 N·mm
  s.force_n = punch ? 2 * u / o.depth_mm * 1e-3 : pressure_kpa * std::numbers::pi * load_radius_mm * load_radius_mm * 1e-3;

  for (double d = 0; d <= o.grid_depth_mm + 1e-9; d += o.grid_step_mm) s.depth_mm.push_back(std::min(d, o.grid_depth_mm));
  for (double r = 0; r <= o.grid_radius_mm + 1e-9; r += o.grid_step_mm) s.r_mm.push_back(r);
  s.von_mises_kpa.resize(s.depth_mm.size() * s.r_mm.size());
  s.sigma_z_kpa.resize(s.von_mises_kpa.size());
  // On the axis the hoop strain u_r/r is its limit ∂u_r/∂r (u_r = 0 there only weakly: dividing by r would amplify it).
  for (const bool axis : {true, false}) {
    getfem::mesh_trans_inv mti(m);
    std::vector<std::size_t> where;
    for (std::size_t k = 0; k < s.depth_mm.size(); ++k)
      for (std::size_t i = axis ? 0 : 1; i < (axis ? 1 : s.r_mm.size()); ++i) {
        mti.add_point(bgeot::base_node{s.r_mm[i], -s.depth_mm[k]});
        where.push_back(k * s.r_mm.size() + i);
      }
    const std::string strain = axis ? std::regex_replace(kStrain, std::regex("u\\(1\\)/X\\(1\\)"), "Grad_u(1,1)") : kStrain;
    getfem::base_vector vm, sz;
    getfem::ga_interpolation_mti(md, strain + kStress + "sqrt(0.5*(sqr(srr-szz)+sqr(szz-stt)+sqr(stt-srr))+3*sqr(srz))", mti, vm);
    getfem::ga_interpolation_mti(md, strain + kStress + "szz", mti, sz);
    for (std::size_t n = 0; n < where.size(); ++n) {
      s.von_mises_kpa[where[n]] = vm[n];
      s.sigma_z_kpa[where[n]] = sz[n];
    }
  }
  return s;
}

}  // namespace

std::vector<TissueLayer> study_fingertip_layers() {
  return {{"epidermis", 0.75, 136, 0.48}, {"dermis", 1.2, 80, 0.48}, {"subcutaneous", 3.0, 34, 0.48},
          {"bone", 2.0, 17e6, 0.30}};
}

void PunchFeOptions::validate() const {
  auto need = [](bool ok, const std::string& field, double v, const char* rule) {
    if (!ok) throw std::invalid_argument(field + " = " + std::to_string(v) + ": " + rule);
  };
  if (layers.empty()) throw std::invalid_argument("layers: at least one layer is needed");
  double total = 0;
  for (const TissueLayer& l : layers) {
    need(std::isfinite(l.thickness_mm) && l.thickness_mm > 0, "layer " + l.name + " thickness_mm", l.thickness_mm, "must be positive");
    need(std::isfinite(l.youngs_kpa) && l.youngs_kpa > 0, "layer " + l.name + " youngs_kpa", l.youngs_kpa, "must be positive");
    need(l.poisson > -1 && l.poisson < 0.5, "layer " + l.name + " poisson", l.poisson, "must be in (-1, 0.5)");
    total += l.thickness_mm;
  }
  need(punch_radius_mm > 0 && punch_radius_mm < domain_radius_mm / 2, "punch_radius_mm", punch_radius_mm,
       "must be positive and below half the domain radius");
  need(depth_mm > 0 && depth_mm < total, "depth_mm", depth_mm, "must be positive and less than the layers' total thickness");
  need(element_mm > 0 && element_mm <= punch_radius_mm / 4, "element_mm", element_mm, "must be positive and at most a quarter of the punch radius");
  need(roi_radius_mm > punch_radius_mm && roi_radius_mm <= domain_radius_mm, "roi_radius_mm", roi_radius_mm,
       "must lie between the punch radius and the domain radius");
  need(roi_depth_mm > 0 && roi_depth_mm <= total, "roi_depth_mm", roi_depth_mm, "must be positive and within the layers");
  need(grid_step_mm > 0 && grid_radius_mm <= domain_radius_mm && grid_depth_mm <= total, "grid_step_mm", grid_step_mm,
       "must be positive, with the grid inside the domain");
}

PunchStress solve_punch_stress(const PunchFeOptions& options) { return solve(options, 0, 0); }

PunchStress solve_disc_load_stress(const PunchFeOptions& options, double load_radius_mm, double pressure_kpa) {
  if (!(load_radius_mm > 0) || !(pressure_kpa > 0)) throw std::invalid_argument("disc load: radius and pressure must be positive");
  return solve(options, load_radius_mm, pressure_kpa);
}

}  // namespace clearfit::study
