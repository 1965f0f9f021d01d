// The state of a simulation: every value that changes while it steps (positions, velocities,
// forces, FEM rotations, solver warm starts, instrument poses and wrenches, contacts, contact
// statistics, time), as one value apart from the model that computes it. A state is captured
// from a simulation, copied, compared, written to a file and restored into any simulation of the
// same model; continuing from it gives bit-identical results to an uninterrupted run.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace viscera {

// Appends values to a component's block of a state, as raw bytes (bit-exact).
class StateWriter {
 public:
  explicit StateWriter(std::vector<char>& out) : out_(out) {}
  template <class T>
  std::enable_if_t<std::is_arithmetic_v<T> || std::is_enum_v<T>> put(const T& v) {
    raw(&v, sizeof(T));
  }
  // A dense Eigen matrix or vector of doubles/ints: its shape, then its coefficients.
  template <class Derived>
  void put(const Eigen::PlainObjectBase<Derived>& m) {
    count(m.rows());
    count(m.cols());
    raw(m.data(), sizeof(typename Derived::Scalar) * m.size());
  }
  // A vector of values of a type put() accepts.
  template <class T, class A>
  void put(const std::vector<T, A>& v) {
    count(static_cast<std::int64_t>(v.size()));
    for (const auto& e : v) put(e);
  }
  // A size or count.
  void count(std::int64_t n) { raw(&n, sizeof n); }
  void raw(const void* p, size_t n) {
    const char* c = static_cast<const char*>(p);
    out_.insert(out_.end(), c, c + n);
  }

 private:
  std::vector<char>& out_;
};

// Reads a component's block back in the order it was written; a block that is too short or too
// long for the model it is restored into is an error (a state of another model).
class StateReader {
 public:
  StateReader(const std::vector<char>& in, std::string what) : in_(in), what_(std::move(what)) {}
  template <class T>
  std::enable_if_t<std::is_arithmetic_v<T> || std::is_enum_v<T>> get(T& v) {
    raw(&v, sizeof(T));
  }
  template <class Derived>
  void get(Eigen::PlainObjectBase<Derived>& m) {
    const std::int64_t r = count(), c = count();
    if (r < 0 || c < 0 || (Derived::RowsAtCompileTime != Eigen::Dynamic && r != Derived::RowsAtCompileTime) ||
        (Derived::ColsAtCompileTime != Eigen::Dynamic && c != Derived::ColsAtCompileTime))
      mismatch("a matrix of another shape");
    need(static_cast<size_t>(r * c) * sizeof(typename Derived::Scalar));
    m.resize(r, c);
    raw(m.data(), sizeof(typename Derived::Scalar) * m.size());
  }
  template <class T, class A>
  void get(std::vector<T, A>& v) {
    const std::int64_t n = count();
    need(static_cast<size_t>(n));  // every element takes at least a byte
    v.resize(n);
    for (auto& e : v) get(e);
  }
  // A size or count written by StateWriter::count (never negative).
  std::int64_t count() {
    std::int64_t n = 0;
    raw(&n, sizeof n);
    if (n < 0) mismatch("a negative count");
    return n;
  }
  void raw(void* p, size_t n) {
    need(n);
    if (n == 0) return;  // an empty array's data() may be null, which memcpy may not be given
    std::memcpy(p, in_.data() + pos_, n);
    pos_ += n;
  }
  size_t remaining() const { return in_.size() - pos_; }
  // Throws unless the whole block was read.
  void finish() const;
  [[noreturn]] void mismatch(const std::string& why) const;

 private:
  void need(size_t n) const {
    if (pos_ + n > in_.size()) mismatch("it ends early");
  }
  const std::vector<char>& in_;
  std::string what_;
  size_t pos_ = 0;
};

// A component whose values change while stepping. It writes them in saveState and reads the
// same values back in loadState; what is recomputed at every step from these (assembled matrices,
// factorisations, bounding volumes) is not state.
class Stateful {
 public:
  virtual ~Stateful() = default;
  virtual void saveState(StateWriter& out) const = 0;
  virtual void loadState(StateReader& in) = 0;
};

struct State {
  // One block per stateful component, in scene order; `component` is its path ("/phantom/fem")
  // and type, so that a state is restored only into a simulation of the same model.
  struct Block {
    std::string component;
    std::vector<char> bytes;
    bool operator==(const Block& o) const { return component == o.component && bytes == o.bytes; }
  };
  double time = 0;
  int steps = 0;
  std::vector<Block> blocks;

  bool operator==(const State& o) const {
    // Bitwise on time, like the blocks: a restored state continues bit-identically.
    return std::memcmp(&time, &o.time, sizeof time) == 0 && steps == o.steps && blocks == o.blocks;
  }
  bool operator!=(const State& o) const { return !(*this == o); }
  // Bytes in all blocks.
  size_t bytes() const;

  // A binary file (magic, version, blocks); written atomically. Errors name the file.
  void save(const std::string& file) const;
  static State load(const std::string& file);
};

}  // namespace viscera
