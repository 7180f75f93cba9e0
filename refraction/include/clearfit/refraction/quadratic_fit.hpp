#pragma once
// Least-squares quadratic in pixel coordinates, 1 + u + v + u² + uv + v²
// with u = (x - cx)·scale, v = (y - cy)·scale, for K values at once; solved
// from the 6x6 normal equations, values taken relative to the first point's.
// Used by the refraction map's boundary resolver (refraction/src/boundary_resolver.cpp)
// to fill the valid pixels behind a traced boundary.
#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace clearfit {

template <int K>
class QuadraticFit {
 public:
  using Row = Eigen::Matrix<double, 1, K>;
  QuadraticFit(double cx, double cy, double scale) : cx_(cx), cy_(cy), scale_(scale) {}

  void add(int x, int y, const Row& value) {
    if (n_++ == 0) origin_ = value;
    const Basis a = basis(x, y);
    ata_.template selfadjointView<Eigen::Lower>().rankUpdate(a.transpose());
    atb_.noalias() += a.transpose() * (value - origin_);
  }
  int size() const { return n_; }
  /// Solves the normal equations. False when the points do not determine all
  /// six terms: fewer than six, or placed so that a term is (nearly) free,
  /// e.g. all on two rows, where v² could be anything between them.
  bool solve() {
    if (n_ < 6) return false;
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>, Eigen::Lower> ldlt(ata_);
    if (ldlt.info() != Eigen::Success) return false;
    // An exactly singular system has a zero pivot (and LDLT's rcond estimate
    // then describes its pseudo-inverse); a nearly singular one a tiny rcond.
    const Eigen::Matrix<double, 6, 1> pivots = ldlt.vectorD().cwiseAbs();
    if (!(pivots.minCoeff() > kMinRcond * pivots.maxCoeff()) || !(ldlt.rcond() > kMinRcond)) return false;
    coef_ = ldlt.solve(atb_);
    return coef_.allFinite();
  }
  /// The fitted values at pixel (x, y); solve() must have returned true.
  Row at(int x, int y) const { return basis(x, y) * coef_ + origin_; }

  static constexpr double kMinRcond = 1e-8;

 private:
  using Basis = Eigen::Matrix<double, 1, 6>;
  Basis basis(int x, int y) const {
    const double u = (x - cx_) * scale_, v = (y - cy_) * scale_;
    return Basis(1, u, v, u * u, u * v, v * v);
  }
  double cx_, cy_, scale_;
  int n_ = 0;
  Row origin_ = Row::Zero();
  Eigen::Matrix<double, 6, 6> ata_ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, K> atb_ = Eigen::Matrix<double, 6, K>::Zero(), coef_ = Eigen::Matrix<double, 6, K>::Zero();
};

}  // namespace clearfit
