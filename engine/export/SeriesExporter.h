// What the frame-series exporters share (VTKExporter: a file per frame; ExodusExporter: one file
// with the mesh once): which body and fields they write, when, the copy of the last step kept
// for a run that diverges between export steps, and the writer thread that encodes and writes
// the frames beside the run.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/Background.h"
#include "core/Component.h"
#include "engine/Roles.h"

namespace viscera {

struct ComponentSpec;
class MechanicalObject;
class TetrahedronFEMForceField;
class VisualModel;

class SeriesExporter : public Component, public Observer {
 public:
  using Component::Component;
  void init() override;
  void begin(const State& s, double t) override;
  void observe(const State& s, double t, int step) override;
  void diverged(const State& s, double t, int step) override;
  void end(const State& s, double t, int step) override;

  // The attributes both exporters take (fields, timing, the body), added to their spec.
  static void addCommonAttributes(ComponentSpec& s);

 protected:
  // What a frame is written from: positions (and, for a volume, velocities and forces when a
  // field needs them).
  struct Frame {
    int step = -1;
    Eigen::Matrix3Xd x, v, f;
    Eigen::VectorXd plastic;  // each element's plastic strain norm (field plasticStrain)
  };
  // Whether field `name` lives on the cells (one value an element) rather than the points.
  static bool cellField(const std::string& name) { return name == "vonMises" || name == "plasticStrain"; }
  // A field of a frame: on the points (3 components a point) or on the cells (one value a cell).
  struct Field {
    std::string name;
    bool onCells = false;
    Eigen::Matrix3Xd points;
    Eigen::VectorXd cells;
  };

  // The series starts (on the run's thread; base() is set) / takes a frame (on the writer thread,
  // in order) / ends (on the writer thread, after the last frame; not called for a run that ends
  // with an exception, whose writer is destroyed instead).
  virtual void startSeries() = 0;
  virtual void writeFrame(double t, int step, const Frame& frame) = 0;
  virtual void finishSeries() {}

  // The fields asked for, in order, computed for a frame.
  std::vector<Field> fieldsOf(const Frame& frame) const;
  const std::vector<std::string>& fieldNames() const { return fields_; }
  bool visual() const { return visual_ != nullptr; }
  const Eigen::Matrix3Xd& rest() const { return rest_; }
  const TetList& tetrahedra() const { return tets_; }
  const Eigen::Matrix<int, 3, Eigen::Dynamic>& triangles() const { return triangles_; }
  // The output path without extension (filename in the output folder).
  const std::string& base() const { return base_; }
  // Finishes the frames handed to the writer thread and stops it. Every exporter's destructor
  // calls it first: the thread calls the exporter's own writeFrame and uses its members.
  void stopWriter() { queue_.reset(); }

 private:
  Frame current(const State& s) const;
  void keep(const State& s, int step);
  void write(double t, int step, Frame fr);

  MechanicalObject* state_ = nullptr;
  TetrahedronFEMForceField* fem_ = nullptr;
  VisualModel* visual_ = nullptr;  // set when writing a visual surface instead of the state
  int every_ = 1;
  bool needV_ = false, needF_ = false, needP_ = false;  // frames carry velocities / forces / plastic strains
  Eigen::Matrix3Xd rest_;  // the rest positions displacements are measured from
  TetList tets_;           // a volume's tetrahedra
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles_;  // a surface's triangles
  std::function<Eigen::VectorXd(const Eigen::Matrix3Xd&)> vonMises_;  // stresses, from a copy of the FEM's rest data
  int lastStep_ = -1;  // the last step handed to the writer
  std::vector<std::string> fields_;
  std::string base_;
  Frame kept_;
  std::unique_ptr<BackgroundQueue> queue_;  // last: finishes its frames before the rest goes
};

}  // namespace viscera
