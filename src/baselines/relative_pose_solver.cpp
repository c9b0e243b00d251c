#include "relative_pose_solver.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <opengv/relative_pose/CentralRelativeAdapter.hpp>
#include <opengv/relative_pose/methods.hpp>
#include <opengv/sac/Ransac.hpp>
#include <opengv/sac_problems/relative_pose/CentralRelativePoseSacProblem.hpp>
#include <opengv/sac_problems/relative_pose/RotationOnlySacProblem.hpp>

namespace omnipose::baselines {
namespace {

namespace ogv = opengv;
using FivePointProblem = ogv::sac_problems::relative_pose::CentralRelativePoseSacProblem;
using RotationProblem = ogv::sac_problems::relative_pose::RotationOnlySacProblem;

/// Angle between f_prev and R f_cur (rotation only).
double rotationResidual(const Eigen::Matrix3d& R, const Eigen::Vector3d& f_prev,
                        const Eigen::Vector3d& f_cur) {
  return std::acos(std::clamp(f_prev.dot(R * f_cur), -1.0, 1.0));
}

/// Angle between f_prev and the epipolar plane spanned by t and R f_cur (f_prev^T E f_cur
/// with E = [t]x R, normalised).
double epipolarResidual(const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                        const Eigen::Vector3d& f_prev, const Eigen::Vector3d& f_cur) {
  const Eigen::Vector3d normal = t.cross(R * f_cur);
  const double n = normal.norm();
  if (n < 1e-12) return rotationResidual(R, f_prev, f_cur);
  return std::asin(std::min(1.0, std::abs(f_prev.dot(normal)) / n));
}

template <typename Problem>
void configure(ogv::sac::Ransac<Problem>& ransac, std::shared_ptr<Problem> problem,
               double threshold, const RelativePoseSettings& s) {
  ransac.sac_model_ = std::move(problem);
  ransac.threshold_ = threshold;
  ransac.max_iterations_ = s.max_iterations;
  ransac.probability_ = s.probability;
}

}  // namespace

RelativePoseResult solveRelativePose(const std::vector<Eigen::Vector3d>& f_previous,
                                     const std::vector<Eigen::Vector3d>& f_current,
                                     const RelativePoseSettings& settings) {
  RelativePoseResult result;
  const ogv::bearingVectors_t b1(f_previous.begin(), f_previous.end());
  const ogv::bearingVectors_t b2(f_current.begin(), f_current.end());
  // Frame 1 = previous, frame 2 = current: OpenGV's R12, t12 give P_1 = R12 P_2 + t12.
  ogv::relative_pose::CentralRelativeAdapter adapter(b1, b2);
  // OpenGV's angular error is 1 - cos(angle) (five-point: summed over both views).
  const double threshold = 1.0 - std::cos(settings.threshold_rad);

  if (settings.solver == Solver::kRotationOnly) {
    // 2-point rotation-only RANSAC; seeded RNG (randomSeed = false) for reproducibility.
    auto problem = std::make_shared<RotationProblem>(adapter, /*randomSeed=*/false);
    ogv::sac::Ransac<RotationProblem> ransac;
    configure(ransac, problem, threshold, settings);
    if (!ransac.computeModel() || ransac.inliers_.size() < 2) return result;
    result.rotation = ransac.model_coefficients_;
    result.inliers = ransac.inliers_;
    result.iterations = ransac.iterations_;
    if (settings.refine) {
      // Least-squares rotation (Arun) on the inliers, then the inliers of the refined model.
      result.rotation = ogv::relative_pose::rotationOnly(adapter, result.inliers);
      problem->selectWithinDistance(result.rotation, threshold, result.inliers);
    }
  } else {
    // Stewenius 5-point essential matrix inside RANSAC, cheirality by triangulation.
    auto problem = std::make_shared<FivePointProblem>(adapter, FivePointProblem::STEWENIUS,
                                                      /*randomSeed=*/false);
    ogv::sac::Ransac<FivePointProblem> ransac;
    configure(ransac, problem, threshold, settings);
    if (!ransac.computeModel() || ransac.inliers_.size() < 5) return result;
    ogv::transformation_t T = ransac.model_coefficients_;
    result.inliers = ransac.inliers_;
    result.iterations = ransac.iterations_;
    if (settings.refine) {
      // Nonlinear refinement on the inliers from the RANSAC model, then its inliers.
      adapter.setR12(T.block<3, 3>(0, 0));
      adapter.sett12(T.col(3));
      const ogv::transformation_t refined =
          ogv::relative_pose::optimize_nonlinear(adapter, result.inliers);
      if (refined.allFinite()) {
        T = refined;
        problem->selectWithinDistance(T, threshold, result.inliers);
      }
    }
    result.rotation = T.block<3, 3>(0, 0);
    const double n = T.col(3).norm();
    result.translation = n > 0 ? Eigen::Vector3d(T.col(3) / n) : Eigen::Vector3d::Zero();
  }

  double sum = 0.0;
  for (int i : result.inliers) {
    const double r =
        settings.solver == Solver::kRotationOnly
            ? rotationResidual(result.rotation, f_previous[i], f_current[i])
            : epipolarResidual(result.rotation, result.translation, f_previous[i], f_current[i]);
    sum += r * r;
  }
  result.residual_rms_rad =
      result.inliers.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(result.inliers.size()));
  result.ok = true;
  return result;
}

}  // namespace omnipose::baselines
