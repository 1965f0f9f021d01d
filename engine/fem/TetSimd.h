// The assembled step's hottest per-element kernels on plain arrays, with vector (AVX2 + FMA)
// versions chosen at run time when the CPU has them: the build targets a baseline x86-64, and these
// loops are a third of the gel phantom's step. The stiffness blocks also have an AVX-512 version
// (the same operations as the AVX2 one, eight entries of a block per vector). The versions compute
// the same results; they differ only in rounding (fused multiply-adds).
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "engine/fem/TetKernel.h"

namespace viscera::fem {

// Adds the stiffness of tetrahedra [first, first + count) to the assembled matrix: the blocks
//   K_ij += a (lambda h_i h_j^T + mu h_j h_i^T + mu (g_i . g_j) I),   h = R^T G,  a = -kFactor V,
// for all 16 node pairs (i, j) of each element, where R is the element's frame (R[e]) and G its
// rest shape-function gradients. `values` holds the matrix's row-major 3 x 3 blocks and
// slots[e] the element's 16 block slots, row-major (slot of (i, j) at 4 i + j); a block whose slot
// is -1 is not stored (upper storage) and is skipped. With firstWriter, bit b of firstWriter[e]
// set means the block at slots[e][b] is set, not added to (its earlier value is ignored): its
// first writer, so that the matrix need not be zeroed first.
void addTetrahedraBlocks(const std::vector<ElementRest>& rest, const Eigen::Matrix3d* R, const std::array<int, 16>* slots,
                         int first, int count, double kFactor, double* values, const std::uint16_t* firstWriter = nullptr);

// The rest data of consecutive elements in groups of eight, one element per lane (structure of
// arrays), for addLargeTetrahedraForces: part of the model, built once.
std::vector<double> largeTetrahedraLanes(const std::vector<ElementRest>& rest);
// The corotational ("large") element force of SOFA's edge frame (fem::frameLarge,
// fem::elementForce) of elements [first, first + count) in one pass, four or eight at a time in the
// vector versions: reads each element's nodes (tets: 4 per element) from positions x (3 x n,
// column-major), writes its frame to R[e] and adds its nodal forces to f (3 x n).
void addLargeTetrahedraForces(const double* x, const int* tets, int first, int count, const std::vector<ElementRest>& rest,
                              const std::vector<double>& lanes, Eigen::Matrix3d* R, double* f);

// The von Mises stress of every corotational ("large") element at positions x (fem::vonMises of
// fem::stress in SOFA's edge frame, as the step computes it), four elements at a time in the
// vector version: out[e] for each element of rest (tets: 4 per element).
void largeTetrahedraVonMises(const double* x, const int* tets, const std::vector<ElementRest>& rest,
                             const std::vector<double>& lanes, double* out);

// The elements' rest orientations (ElementRest::sign), contiguous, for invertedTetrahedra: part of
// the model, built once.
std::vector<double> restSigns(const std::vector<ElementRest>& rest);
// The elements whose orientation at x (3 x n) differs from their rest orientation (sign, one per
// element), or is degenerate: the health check after each step, four or eight elements at a time.
std::vector<int> invertedTetrahedra(const double* x, const int* tets, const std::vector<double>& sign);

// Which version the kernels run: "avx512" (the stiffness blocks and forces; the others AVX2), "avx2" or
// "generic".
const char* tetrahedronKernelsVersion();

}  // namespace viscera::fem
