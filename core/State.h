// The state of a simulation: every value that changes while it steps (positions, velocities,
// forces, FEM rotations, solver warm starts, instrument poses and wrenches, contacts, contact
// statistics, time), apart from the model that computes it. The components of a built scene are
// the model: they hold parameters and what is precomputed from them, and are read-only while
// stepping, so that several simulations of one model step at once in threads.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <cstring>
#include <memory>
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
  // A vector that must keep the size `v` has in this model (one value per element, per spring):
  // read into `v`, or a mismatch naming the count and `what` it counts.
  template <class T, class A>
  void getSameSize(std::vector<T, A>& v, const char* what) {
    std::vector<T, A> in;
    get(in);
    if (in.size() != v.size())
      mismatch(std::to_string(in.size()) + " " + what + " where this component has " + std::to_string(v.size()));
    v = std::move(in);
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

// The changing values of one component in one simulation (a MechanicalObject's x, v and f, the
// FEM's element frames, a solver's warm start), and the scratch it recomputes every step. `save`
// writes what a saved state keeps, `load` reads it back; scratch is neither saved nor compared.
class ComponentState {
 public:
  virtual ~ComponentState() = default;
  virtual std::unique_ptr<ComponentState> clone() const = 0;
  virtual void save(StateWriter& out) const = 0;
  virtual void load(StateReader& in) = 0;
};

// Base of a component's state struct D: copying a state copies D.
template <class D>
class ComponentStateOf : public ComponentState {
 public:
  std::unique_ptr<ComponentState> clone() const override {
    return std::make_unique<D>(static_cast<const D&>(*this));
  }
};

// Scratch a component rebuilds as it steps (factorisations, caches): each copy of a state starts
// with its own, empty one, so that states never share it.
template <class T>
class Scratch {
 public:
  Scratch() = default;
  Scratch(const Scratch&) {}
  Scratch& operator=(const Scratch&) {
    p_.reset();
    return *this;
  }
  T& get() {
    if (!p_) p_ = std::make_unique<T>();
    return *p_;
  }
  T* operator->() { return &get(); }
  bool empty() const { return !p_; }
  void reset() { p_.reset(); }

 private:
  std::unique_ptr<T> p_;
};

class State;

// The role of a component whose values change while stepping: it holds none of them itself, but
// makes the block a simulation keeps them in, and finds that block in a State.
class Stateful {
 public:
  virtual ~Stateful() = default;
  // The values at the start of a simulation (after init).
  virtual std::unique_ptr<ComponentState> initialState() const = 0;
  // The index of this component's block in the states of its model (set once, when the first
  // simulation of the model is made).
  int stateSlot() const { return slot_; }
  void setStateSlot(int slot) { slot_ = slot; }

 protected:
  template <class D>
  D& stateIn(State& s) const;
  template <class D>
  const D& stateIn(const State& s) const;

 private:
  int slot_ = -1;
};

// The state of one simulation: time, steps and one block per stateful component, in scene order.
// The simulation steps it in place; a copy is a snapshot (deep), compared bitwise, written to a
// file and restored into any simulation of the same model, where continuing from it gives
// bit-identical results to an uninterrupted run. A state read from a file holds its blocks as
// bytes until it is restored.
class State {
 public:
  double time = 0;
  int steps = 0;

  State() = default;
  State(const State& o);
  State& operator=(const State& o);
  State(State&&) = default;
  State& operator=(State&&) = default;

  // A block for component `name` (its path and type) holding `data`.
  void add(std::string name, std::unique_ptr<ComponentState> data);
  size_t blockCount() const { return blocks_.size(); }
  const std::string& component(size_t i) const { return blocks_[i].component; }
  // Block i as saved bytes.
  std::vector<char> bytesOf(size_t i) const;
  template <class D>
  D& of(int slot) {
    return static_cast<D&>(live(slot));
  }
  template <class D>
  const D& of(int slot) const {
    return static_cast<const D&>(const_cast<State*>(this)->live(slot));
  }

  // Bitwise on the time and on every block's saved values.
  bool operator==(const State& o) const;
  bool operator!=(const State& o) const { return !(*this == o); }
  // Bytes in all blocks, as saved.
  size_t bytes() const;

  // A binary file (magic, version, blocks); written atomically. Errors name the file.
  void save(const std::string& file) const;
  static State load(const std::string& file);

 private:
  struct Block {
    std::string component;
    std::unique_ptr<ComponentState> data;  // live values; null in a state read from a file
    std::vector<char> saved;               // the values as bytes when `data` is null
  };
  ComponentState& live(int slot);
  std::vector<Block> blocks_;
};

template <class D>
D& Stateful::stateIn(State& s) const {
  return s.of<D>(slot_);
}
template <class D>
const D& Stateful::stateIn(const State& s) const {
  return s.of<D>(slot_);
}

}  // namespace viscera
