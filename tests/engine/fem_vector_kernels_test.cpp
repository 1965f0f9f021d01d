// The hand-vectorised kernels of the assembled step (engine/fem/TetSimd.h, the block product of
// solvers/linear/BlockSparseMatrix) against the Eigen definitions in engine/fem/TetKernel.h and
// a dense product. The same tests run once more under VISCERA_SIMD=generic and VISCERA_SIMD=avx2
// (tests/CMakeLists.txt), so every version the CPU has is checked. Tolerance 1e-12 relative: the versions differ
// only in the order of a few dozen floating-point operations (and in fused multiply-adds).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "builtin/Builtins.h"
#include "core/Scene.h"
#include "engine/Simulation.h"
#include "engine/fem/TetKernel.h"
#include "engine/fem/TetSimd.h"
#include "engine/mechanics/MechanicalObject.h"
#include "solvers/linear/BlockSparseMatrix.h"
#include "tests/support/SceneFiles.h"

namespace fem = viscera::fem;
using namespace viscera;

namespace {

std::mt19937_64 rng(7);
double uniform(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); }

// A well-shaped tetrahedron, moved by a random rotation and stretch.
fem::Mat34 randomTetrahedron() {
  fem::Mat34 p;
  p << 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1;
  for (int i = 0; i < 12; ++i) p.data()[i] += uniform(-0.2, 0.2);
  return p;
}

TEST(VectorKernels, LargeForceMatchesTheEigenKernel) {
  SCOPED_TRACE(fem::tetrahedronKernelsVersion());
  for (int trial = 0; trial < 200; ++trial) {
    const fem::Mat34 rest = randomTetrahedron();
    const fem::ElementRest e = fem::restElement(fem::Method::Large, rest, fem::Lame::fromYoungPoisson(uniform(1e3, 1e6), 0.45));
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(uniform(-3, 3), Eigen::Vector3d::Random().normalized()).toRotationMatrix();
    fem::Mat34 x = turn * rest;
    for (int i = 0; i < 12; ++i) x.data()[i] += uniform(-0.1, 0.1);
    Eigen::Matrix3d Rref;
    const fem::Mat34 fref = fem::elementForce(fem::Method::Large, e, x, Rref);

    // Nodes 3 2 0 1 of a five-node state: the kernel gathers and scatters through the indices.
    const int nodes[4] = {3, 2, 0, 1};
    Eigen::Matrix3Xd X = Eigen::Matrix3Xd::Zero(3, 5), f = Eigen::Matrix3Xd::Ones(3, 5);
    for (int k = 0; k < 4; ++k) X.col(nodes[k]) = x.col(k);
    Eigen::Matrix3d R;
    fem::addLargeTetrahedraForces(X.data(), nodes, 0, 1, {e}, fem::largeTetrahedraLanes({e}), &R, f.data());
    EXPECT_LT((R - Rref).cwiseAbs().maxCoeff(), 1e-12);
    const double scale = fref.cwiseAbs().maxCoeff();
    for (int k = 0; k < 4; ++k)
      for (int r = 0; r < 3; ++r) EXPECT_LE(std::abs(f(r, nodes[k]) - 1.0 - fref(r, k)), 1e-12 * scale) << trial;
    EXPECT_EQ(f.col(4), Eigen::Vector3d::Ones());
  }
}

// A chain of `count` elements sharing nodes: element e on nodes e .. e + 3 of rest, with Young's
// modulus young(e) (called in element order) and Poisson ratio 0.4.
struct Chain {
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets;
  std::vector<fem::ElementRest> elements;
};
template <class Young>
Chain chainOf(const Eigen::Matrix3Xd& rest, int count, Young young) {
  Chain c{Eigen::Matrix<int, 4, Eigen::Dynamic>(4, count), {}};
  for (int e = 0; e < count; ++e) {
    c.tets.col(e) << e, e + 1, e + 2, e + 3;
    fem::Mat34 X;
    for (int k = 0; k < 4; ++k) X.col(k) = rest.col(e + k);
    c.elements.push_back(fem::restElement(fem::Method::Large, X, fem::Lame::fromYoungPoisson(young(e), 0.4)));
  }
  return c;
}

// Elements 0..14 of a chain sharing nodes (e uses nodes e .. e + 3). From element 0: 0..7 in
// eight lanes (AVX-512) or two groups of four, 8..11 in four, 12..14 one by one; from element 1:
// 1..3 and 12..14 one by one, 4..7 and 8..11 in four lanes.
TEST(VectorKernels, LargeForcesOfARangeMatchTheEigenKernel) {
  const int count = 15, nodes = count + 3;
  Eigen::Matrix3Xd rest(3, nodes);
  for (int i = 0; i < nodes; ++i) rest.col(i) = Eigen::Vector3d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1));
  const auto [tets, elements] = chainOf(rest, count, [](int) { return uniform(1e3, 1e5); });
  const std::vector<double> lanes = fem::largeTetrahedraLanes(elements);
  Eigen::Matrix3Xd x = rest;
  for (int i = 0; i < 3 * nodes; ++i) x.data()[i] += uniform(-0.05, 0.05);
  for (int first : {0, 1}) {
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, nodes), fref = Eigen::Matrix3Xd::Zero(3, nodes);
    std::vector<Eigen::Matrix3d> R(count, Eigen::Matrix3d::Zero());
    fem::addLargeTetrahedraForces(x.data(), tets.data(), first, count - first, elements, lanes, R.data(), f.data());
    for (int e = first; e < count; ++e) {
      fem::Mat34 xe;
      for (int k = 0; k < 4; ++k) xe.col(k) = x.col(tets(k, e));
      Eigen::Matrix3d Rref;
      const fem::Mat34 fe = fem::elementForce(fem::Method::Large, elements[e], xe, Rref);
      for (int k = 0; k < 4; ++k) fref.col(tets(k, e)) += fe.col(k);
      EXPECT_LT((R[e] - Rref).cwiseAbs().maxCoeff(), 1e-12) << e;
    }
    EXPECT_LE((f - fref).cwiseAbs().maxCoeff(), 1e-12 * fref.cwiseAbs().maxCoeff()) << first;
  }
}

// Eleven elements on their own nodes (two groups of four in the lanes, three one by one), each
// turned and strained at random: the von Mises stress of each against the Eigen definition
// (fem::vonMises of fem::stress in SOFA's edge frame).
TEST(VectorKernels, VonMisesMatchesTheEigenKernel) {
  SCOPED_TRACE(fem::tetrahedronKernelsVersion());
  const int n = 11;
  std::vector<fem::ElementRest> rest;
  Eigen::Matrix3Xd X(3, 4 * n);
  std::vector<int> tets;
  std::vector<double> expected;
  for (int e = 0; e < n; ++e) {
    const fem::Mat34 r = randomTetrahedron();
    rest.push_back(fem::restElement(fem::Method::Large, r, fem::Lame::fromYoungPoisson(uniform(1e3, 1e6), uniform(0.1, 0.49))));
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(uniform(-3, 3), Eigen::Vector3d::Random().normalized()).toRotationMatrix();
    fem::Mat34 x = turn * r;
    for (int i = 0; i < 12; ++i) x.data()[i] += uniform(-0.1, 0.1);
    // Stored in reverse node order in the state: the kernel gathers through the indices.
    for (int k = 0; k < 4; ++k) {
      X.col(4 * n - 1 - (4 * e + k)) = x.col(k);
      tets.push_back(4 * n - 1 - (4 * e + k));
    }
    const Eigen::Matrix3d R = fem::frame(fem::Method::Large, x);
    expected.push_back(fem::vonMises(fem::stress(rest.back(), fem::localPositions(fem::Method::Large, R, x) - rest.back().X)));
  }
  std::vector<double> vm(n, -1.0);
  fem::largeTetrahedraVonMises(X.data(), tets.data(), rest, fem::largeTetrahedraLanes(rest), vm.data());
  for (int e = 0; e < n; ++e) {
    EXPECT_GT(expected[e], 0.0);
    EXPECT_LE(std::abs(vm[e] - expected[e]), 1e-12 * expected[e]) << "element " << e;
  }
}

// 25 elements (three groups of eight, or six of four, then one alone), some turned inside out by
// moving a node through node 0, one with no volume, one not a number; the last group has none.
TEST(VectorKernels, InvertedElementsAreTheOnesWithTheOtherOrientation) {
  const int count = 25;
  Eigen::Matrix3Xd x(3, 4 * count);
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets(4, count);
  std::vector<fem::ElementRest> elements;
  std::vector<int> expected;
  for (int e = 0; e < count; ++e) {
    const fem::Mat34 rest = randomTetrahedron() * (e % 2 ? 1.0 : -1.0);  // both rest orientations
    elements.push_back(fem::restElement(fem::Method::Large, rest, fem::Lame::fromYoungPoisson(1e3, 0.3)));
    fem::Mat34 now = rest;
    if (e % 3 == 0 && e < 16) {
      now.col(3) = rest.col(0) + (rest.col(0) - rest.col(3));  // node 3 through node 0: inverted
      expected.push_back(e);
    } else if (e == 7) {
      now.col(3) = rest.col(0);  // node 3 on node 0: no volume
      expected.push_back(e);
    } else if (e == 10) {
      now(1, 2) = std::numeric_limits<double>::quiet_NaN();  // no orientation at all
      expected.push_back(e);
    }
    for (int k = 0; k < 4; ++k) {
      tets(k, e) = 4 * e + k;
      x.col(4 * e + k) = now.col(k);
    }
  }
  EXPECT_EQ(fem::invertedTetrahedra(x.data(), tets.data(), fem::restSigns(elements)), expected);
}

// On a CPU with AVX2 and FMA the vector versions run, and the AVX-512 ones where it also has
// AVX-512F and VL, unless the environment asks for less.
TEST(VectorKernels, TheVectorVersionsRunWhereTheCpuHasThem) {
  const std::string forced = std::getenv("VISCERA_SIMD") ? std::getenv("VISCERA_SIMD") : "";
  __builtin_cpu_init();
  const bool avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && forced != "generic";
  const bool avx512 = avx2 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") && forced != "avx2";
  EXPECT_STREQ(fem::tetrahedronKernelsVersion(), avx512 ? "avx512" : avx2 ? "avx2" : "generic");
}

// A collapsed element (all nodes on one point) gets a zero frame and finite forces, as in the
// Eigen kernel, so that the health check can name it.
TEST(VectorKernels, ACollapsedElementHasFiniteForces) {
  const fem::ElementRest e = fem::restElement(fem::Method::Large, randomTetrahedron(), fem::Lame::fromYoungPoisson(1e3, 0.3));
  const int count = 13;  // eight lanes or two groups of four, a group of four, one alone
  const std::vector<fem::ElementRest> rest(count, e);
  const std::vector<double> lanes = fem::largeTetrahedraLanes(rest);
  Eigen::Matrix<int, 4, Eigen::Dynamic> tets(4, count);
  for (int k = 0; k < count; ++k) tets.col(k) << 0, 1, 2, 3;
  const Eigen::Matrix3Xd x = Eigen::Matrix3Xd::Ones(3, 4);
  Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, 4);
  std::vector<Eigen::Matrix3d> R(count);
  fem::addLargeTetrahedraForces(x.data(), tets.data(), 0, count, rest, lanes, R.data(), f.data());
  Eigen::Matrix3d Rref;
  fem::Mat34 xe = fem::Mat34::Ones();
  const fem::Mat34 fref = fem::elementForce(fem::Method::Large, e, xe, Rref);
  EXPECT_TRUE(f.allFinite());
  EXPECT_LE((f - count * fref).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, fref.cwiseAbs().maxCoeff()));
  for (const auto& r : R) EXPECT_EQ(r, Rref);
}

TEST(VectorKernels, StiffnessBlocksMatchTheEigenKernel) {
  SCOPED_TRACE(fem::tetrahedronKernelsVersion());
  for (int trial = 0; trial < 200; ++trial) {
    const fem::Mat34 rest = randomTetrahedron();
    const fem::ElementRest e = fem::restElement(fem::Method::Large, rest, fem::Lame::fromYoungPoisson(uniform(1e3, 1e6), 0.3));
    fem::Mat34 x = rest;
    for (int i = 0; i < 12; ++i) x.data()[i] += uniform(-0.1, 0.1);
    const Eigen::Matrix3d R = fem::frame(fem::Method::Large, x);
    const double kFactor = uniform(-2, 2);
    const fem::Mat12 Kref = kFactor * fem::elementStiffness(fem::Method::Large, e, R);

    // Element nodes 2 0 3 1 of a four-node matrix that already holds values.
    const int nodes[4] = {2, 0, 3, 1};
    BlockSparseMatrix K;
    K.setPattern(4, {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}});
    for (int s = 0; s < K.nonZeroBlocks(); ++s) K.block(s).setConstant(0.5);
    std::array<int, 16> slots;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) slots[4 * i + j] = K.slot(nodes[i], nodes[j]);
    fem::addTetrahedraBlocks({e}, &R, &slots, 0, 1, kFactor, K.values());
    const Eigen::MatrixXd dense = K.toDense();
    const double scale = Kref.cwiseAbs().maxCoeff();
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        const Eigen::Matrix3d got = dense.block<3, 3>(3 * nodes[i], 3 * nodes[j]).array() - 0.5;
        EXPECT_LE((got - Kref.block<3, 3>(3 * i, 3 * j)).cwiseAbs().maxCoeff(), 1e-12 * scale) << trial << " " << i << j;
      }
  }
}

// Elements 2..6 of a chain (element e on nodes e .. e + 3) added in one call: each element's frame,
// rest data and slots are found by its index.
TEST(VectorKernels, StiffnessBlocksOfARangeMatchTheEigenKernel) {
  const int count = 7, nodes = count + 3;
  std::vector<fem::ElementRest> elements;
  std::vector<Eigen::Matrix3d> R;
  std::vector<std::pair<int, int>> pairs;
  for (int e = 0; e < count; ++e) {
    elements.push_back(fem::restElement(fem::Method::Large, randomTetrahedron(), fem::Lame::fromYoungPoisson(uniform(1e3, 1e5), 0.35)));
    R.push_back(Eigen::AngleAxisd(uniform(-3, 3), Eigen::Vector3d::Random().normalized()).toRotationMatrix());
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) pairs.push_back({e + i, e + j});
  }
  BlockSparseMatrix K;
  K.setPattern(nodes, pairs);
  std::vector<std::array<int, 16>> slots(count);
  for (int e = 0; e < count; ++e)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) slots[e][4 * i + j] = K.slot(e + i, e + j);
  const double kFactor = 0.7;
  fem::addTetrahedraBlocks(elements, R.data(), slots.data(), 2, 5, kFactor, K.values());
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(3 * nodes, 3 * nodes);
  for (int e = 2; e < 7; ++e) {
    const fem::Mat12 Ke = kFactor * fem::elementStiffness(fem::Method::Large, elements[e], R[e]);
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) ref.block<3, 3>(3 * (e + i), 3 * (e + j)) += Ke.block<3, 3>(3 * i, 3 * j);
  }
  EXPECT_LE((K.toDense() - ref).cwiseAbs().maxCoeff(), 1e-12 * ref.cwiseAbs().maxCoeff());
}

// A fingerprint of the element forces, frames and stiffness blocks of a chain of elements, as this
// process's kernels compute them (the bits of every value, hashed).
std::string kernelFingerprint() {
  std::mt19937_64 gen(11);
  std::uniform_real_distribution<double> u(-1, 1);
  const int count = 37, nodes = count + 3;  // groups of eight and of four, and single elements
  Eigen::Matrix3Xd rest(3, nodes), x(3, nodes);
  for (int i = 0; i < 3 * nodes; ++i) rest.data()[i] = u(gen);
  for (int i = 0; i < 3 * nodes; ++i) x.data()[i] = rest.data()[i] + 0.05 * u(gen);
  const auto [tets, elements] = chainOf(rest, count, [&](int) { return 1e3 + 1e4 * (1 + u(gen)); });
  Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, nodes);
  std::vector<Eigen::Matrix3d> R(count);
  fem::addLargeTetrahedraForces(x.data(), tets.data(), 0, count, elements, fem::largeTetrahedraLanes(elements), R.data(), f.data());
  std::vector<std::array<int, 16>> slots(count);
  for (int e = 0; e < count; ++e)
    for (int k = 0; k < 16; ++k) slots[e][k] = 16 * e + k;
  std::vector<double> blocks(9 * 16 * count + 1, 0.0);
  fem::addTetrahedraBlocks(elements, R.data(), slots.data(), 0, count, 0.3, blocks.data());
  unsigned long long h = 1469598103934665603ULL;  // FNV-1a over the values' bits
  auto mix = [&](const double* v, size_t n) {
    for (size_t i = 0; i < n; ++i) {
      unsigned long long b;
      std::memcpy(&b, v + i, sizeof b);
      h = (h ^ b) * 1099511628211ULL;
    }
  };
  mix(f.data(), f.size());
  for (const auto& r : R) mix(r.data(), 9);
  mix(blocks.data(), blocks.size());
  char text[32];
  std::snprintf(text, sizeof text, "%016llx", h);
  return text;
}

// Prints kernelFingerprint(); run by the test below in a process of its own.
TEST(VectorKernels, DISABLED_PrintFingerprint) { std::printf("fingerprint %s\n", kernelFingerprint().c_str()); }

// The AVX-512 forces and blocks give the AVX2 ones' results to the bit: this process's fingerprint
// against that of the same test binary run with VISCERA_SIMD=avx2.
TEST(VectorKernels, Avx512VersionsGiveTheAvx2ResultsToTheBit) {
  if (std::string(fem::tetrahedronKernelsVersion()) != "avx512") GTEST_SKIP() << "runs the AVX-512 kernels only";
  const std::string self = std::filesystem::read_symlink("/proc/self/exe").string();
  FILE* child = popen(("VISCERA_SIMD=avx2 '" + self +
                       "' --gtest_also_run_disabled_tests --gtest_filter=VectorKernels.DISABLED_PrintFingerprint 2>&1")
                          .c_str(),
                      "r");
  ASSERT_NE(child, nullptr);
  std::string out;
  char buf[4096];
  while (size_t n = std::fread(buf, 1, sizeof buf, child)) out.append(buf, n);
  ASSERT_EQ(pclose(child), 0) << out;
  const size_t at = out.find("fingerprint ");
  ASSERT_NE(at, std::string::npos) << out;
  EXPECT_EQ(out.substr(at + 12, 16), kernelFingerprint());
}

// The same elements assembled into upper storage: each stored block (i <= j) is the full
// storage's block (i, j) to the bit; nothing is written below the diagonal.
TEST(VectorKernels, StiffnessBlocksInUpperStorageAreTheFullOnes) {
  const int count = 9, nodes = count + 3;
  const int number[nodes] = {5, 11, 0, 7, 2, 9, 1, 10, 3, 8, 4, 6};  // node numbers out of element order
  std::vector<fem::ElementRest> elements;
  std::vector<Eigen::Matrix3d> R;
  std::vector<std::pair<int, int>> pairs;
  for (int e = 0; e < count; ++e) {
    elements.push_back(fem::restElement(fem::Method::Large, randomTetrahedron(), fem::Lame::fromYoungPoisson(uniform(1e3, 1e5), 0.45)));
    R.push_back(Eigen::AngleAxisd(uniform(-3, 3), Eigen::Vector3d::Random().normalized()).toRotationMatrix());
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) pairs.push_back({number[e + i], number[e + j]});
  }
  BlockSparseMatrix full, upper;
  full.setPattern(nodes, pairs);
  upper.setPattern(nodes, pairs, BlockSparseMatrix::Storage::Upper);
  for (BlockSparseMatrix* K : {&full, &upper}) {
    std::vector<std::array<int, 16>> slots(count);
    for (int e = 0; e < count; ++e)
      for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) slots[e][4 * i + j] = K->slot(number[e + i], number[e + j]);
    fem::addTetrahedraBlocks(elements, R.data(), slots.data(), 0, count, -0.3, K->values());
  }
  EXPECT_EQ(upper.values()[9 * upper.nonZeroBlocks()], 0.0);  // the padding after the last block
  int compared = 0;
  for (int i = 0; i < nodes; ++i)
    for (int j = i; j < nodes; ++j)
      if (const int s = full.slot(i, j); s >= 0) {
        ASSERT_GE(upper.slot(i, j), 0);
        EXPECT_TRUE(upper.block(upper.slot(i, j)) == full.block(s)) << i << " " << j;
        ++compared;
      }
  EXPECT_EQ(compared, upper.nonZeroBlocks());
  const Eigen::MatrixXd F = full.toDense();
  EXPECT_LE((upper.toDense() - F).cwiseAbs().maxCoeff(), 1e-13 * F.cwiseAbs().maxCoeff());
}

// With first-writer bits the matrix need not be zeroed: each block is set by its first writer,
// whatever it held (not a number here), and the matrix is the zeroed one's to the bit. Both
// storages, elements sharing nodes out of order.
TEST(VectorKernels, FirstWritersSetTheirBlocks) {
  const int count = 13, nodes = count + 3;
  std::vector<fem::ElementRest> elements;
  std::vector<Eigen::Matrix3d> R;
  std::vector<std::pair<int, int>> pairs;
  std::vector<int> number(nodes);
  for (int i = 0; i < nodes; ++i) number[i] = (7 * i) % nodes;  // a permutation: 7 and 16 are coprime
  for (int e = 0; e < count; ++e) {
    elements.push_back(fem::restElement(fem::Method::Large, randomTetrahedron(), fem::Lame::fromYoungPoisson(uniform(1e3, 1e5), 0.45)));
    R.push_back(Eigen::AngleAxisd(uniform(-3, 3), Eigen::Vector3d::Random().normalized()).toRotationMatrix());
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) pairs.push_back({number[e + i], number[e + j]});
  }
  for (auto storage : {BlockSparseMatrix::Storage::Full, BlockSparseMatrix::Storage::Upper}) {
    BlockSparseMatrix zeroed, set;
    zeroed.setPattern(nodes, pairs, storage);
    set.setPattern(nodes, pairs, storage);
    std::vector<std::array<int, 16>> slots(count);
    std::vector<std::uint16_t> first(count, 0);
    std::vector<char> written(zeroed.nonZeroBlocks(), 0);
    for (int e = 0; e < count; ++e)
      for (int b = 0; b < 16; ++b) {
        slots[e][b] = zeroed.slot(number[e + b / 4], number[e + b % 4]);
        if (slots[e][b] >= 0 && !written[slots[e][b]]) {
          written[slots[e][b]] = 1;
          first[e] |= static_cast<std::uint16_t>(1u << b);
        }
      }
    ASSERT_EQ(std::count(written.begin(), written.end(), 1), zeroed.nonZeroBlocks());
    std::fill_n(set.values(), 9 * set.nonZeroBlocks(), std::nan(""));
    fem::addTetrahedraBlocks(elements, R.data(), slots.data(), 0, count, -0.3, zeroed.values());
    fem::addTetrahedraBlocks(elements, R.data(), slots.data(), 0, count, -0.3, set.values(), first.data());
    EXPECT_EQ(std::memcmp(zeroed.values(), set.values(), sizeof(double) * 9 * zeroed.nonZeroBlocks()), 0)
        << (storage == BlockSparseMatrix::Storage::Upper ? "upper" : "full");
  }
}

TEST(VectorKernels, BlockProductMatchesTheDenseProduct) {
  for (int n : {1, 2, 7, 600}) {  // 600 rows: the parallel path
    std::vector<std::pair<int, int>> pairs;
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < 6; ++k) pairs.push_back({i, static_cast<int>(uniform(0, n - 1e-9))});
    BlockSparseMatrix A;
    A.setPattern(n, pairs);
    for (int s = 0; s < A.nonZeroBlocks(); ++s) A.block(s) = Eigen::Matrix3d::Random();
    const Eigen::VectorXd x = Eigen::VectorXd::Random(3 * n);
    Eigen::VectorXd y(3 * n);
    A.multiply(x, y);
    const Eigen::VectorXd ref = A.toDense() * x;
    EXPECT_LE((y - ref).cwiseAbs().maxCoeff(), 1e-13 * std::max(1.0, ref.cwiseAbs().maxCoeff())) << n;
  }
}

// Elements are colored in runs that one thread walks: the phantom's positions after 20 steps are
// the same to the bit on one and on two threads.
TEST(VectorKernels, StepDoesNotDependOnTheThreadCount) {
  Eigen::Matrix3Xd x[2];
  for (int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    auto scene = buildScene(test_support::readSceneWithoutExports("scenes/gel_phantom.xml"));
    Simulation sim(*scene);
    for (int i = 0; i < 20; ++i) ASSERT_FALSE(sim.step());
    x[threads - 1] = scene->all<MechanicalObject>().at(0)->x(sim.state());
  }
  EXPECT_TRUE(x[0] == x[1]) << "largest difference " << (x[0] - x[1]).cwiseAbs().maxCoeff();
}

}  // namespace
