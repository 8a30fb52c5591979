// Palm FK and FK + Jacobian + manipulability on the seed-000 chain
// (config/models/macaque_exo.yaml), exodaq and KDL side by side in one run.
// Run: bench/kinematics/kdl_ratio.sh BUILD_DIR (prints ns/call and the ratios).
#include <benchmark/benchmark.h>

#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/jacobian.hpp>
#include <kdl/jntarray.hpp>
#include <random>
#include <vector>

#include "exodaq/config/model_file.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"

namespace {

using exodaq::kin::JointVector;

struct Fixture {
  exodaq::config::KinematicModel model;
  KDL::Chain kdl;
  std::vector<JointVector> qs;
  std::vector<KDL::JntArray> qs_kdl;

  Fixture()
      : model(exodaq::config::load_model_file(std::string(EXODAQ_SOURCE_DIR) +
                                              "/config/models/macaque_exo.yaml")) {
    for (const auto& j : model.chain.joints()) {
      kdl.addSegment(KDL::Segment(j.name, KDL::Joint(KDL::Joint::RotZ),
                                  KDL::Frame::DH(j.dh.a, j.dh.alpha, j.dh.d, j.dh.theta_offset)));
    }
    std::mt19937_64 rng(42);
    const int n = model.chain.joint_count();
    for (int k = 0; k < 1024; ++k) {
      JointVector q(n);
      KDL::JntArray qk(static_cast<unsigned>(n));
      for (int i = 0; i < n; ++i) {
        const auto& l = model.chain.joints()[static_cast<std::size_t>(i)].limits;
        q[i] = std::uniform_real_distribution<double>(l.lower, l.upper)(rng);
        qk(static_cast<unsigned>(i)) = q[i];
      }
      qs.push_back(q);
      qs_kdl.push_back(qk);
    }
  }
};

const Fixture& fixture() {
  static const Fixture f;
  return f;
}

void BM_PalmFk_Exodaq(benchmark::State& state) {
  const auto& f = fixture();
  std::size_t k = 0;
  for (auto _ : state) {
    exodaq::kin::Pose p = f.model.chain.palm(f.qs[k++ & 1023]);
    benchmark::DoNotOptimize(p);
  }
}

void BM_PalmFk_Kdl(benchmark::State& state) {
  const auto& f = fixture();
  KDL::ChainFkSolverPos_recursive fk(f.kdl);
  KDL::Frame p;
  std::size_t k = 0;
  for (auto _ : state) {
    fk.JntToCart(f.qs_kdl[k++ & 1023], p);
    benchmark::DoNotOptimize(p);
  }
}

// Palm pose, 6x6 palm Jacobian and the positional manipulability sqrt(det(Jv Jv^T)).
void BM_FkJacManip_Exodaq(benchmark::State& state) {
  const auto& f = fixture();
  exodaq::kin::Pose p;
  exodaq::kin::Jacobian J;
  std::size_t k = 0;
  for (auto _ : state) {
    f.model.chain.palm_and_jacobian(f.qs[k++ & 1023], p, J);
    double w = exodaq::kin::manipulability(J, exodaq::kin::kLinearRows);
    benchmark::DoNotOptimize(p);
    benchmark::DoNotOptimize(w);
  }
}

void BM_FkJacManip_Kdl(benchmark::State& state) {
  const auto& f = fixture();
  KDL::ChainFkSolverPos_recursive fk(f.kdl);
  KDL::ChainJntToJacSolver jac(f.kdl);
  KDL::Frame p;
  KDL::Jacobian J(f.kdl.getNrOfJoints());
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& q = f.qs_kdl[k++ & 1023];
    fk.JntToCart(q, p);
    jac.JntToJac(q, J);
    const Eigen::Matrix3d g = J.data.topRows<3>() * J.data.topRows<3>().transpose();
    double w = std::sqrt(std::max(0.0, g.determinant()));
    benchmark::DoNotOptimize(p);
    benchmark::DoNotOptimize(w);
  }
}

// What the daemon runs every cycle: palm pose + quaternion, elbow, shoulder manipulability.
void BM_EvaluateRig_Exodaq(benchmark::State& state) {
  const auto& f = fixture();
  exodaq::kin::RigPose out;
  std::size_t k = 0;
  for (auto _ : state) {
    exodaq::kin::evaluate_rig(f.model.chain, f.model.rig, f.qs[k++ & 1023], out);
    benchmark::DoNotOptimize(out);
  }
}

BENCHMARK(BM_PalmFk_Exodaq);
BENCHMARK(BM_PalmFk_Kdl);
BENCHMARK(BM_FkJacManip_Exodaq);
BENCHMARK(BM_FkJacManip_Kdl);
BENCHMARK(BM_EvaluateRig_Exodaq);

}  // namespace

BENCHMARK_MAIN();
