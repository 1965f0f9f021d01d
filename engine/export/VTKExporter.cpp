// VTKExporter: writes the MechanicalObject of its node as a .vtu series with a .pvd index
// (ParaView), with point fields displacement and velocity and the cell field vonMises; in a node
// with a visual model (OglModel/VisualModel), that surface as a .vtp series with displacement.
#include <cstdio>
#include <filesystem>

#include "core/Registry.h"
#include "engine/export/SeriesExporter.h"
#include "io/mesh/Mesh.h"

namespace viscera {

namespace {

class VTKExporter : public SeriesExporter {
 public:
  using SeriesExporter::SeriesExporter;
  ~VTKExporter() override { stopWriter(); }
  void init() override {
    SeriesExporter::init();
    // Compressed frames also store connectivity and offsets as Int32; uncompressed ones keep the
    // plain Int64 layout.
    options_.compress = options_.int32Indices = attrs_.boolean("compress");
    options_.float32 = attrs_.str("precision") == "float32";
  }

 private:
  void startSeries() override {
    written_.clear();
    // A volume's tetrahedra are encoded and compressed once for the whole series.
    if (!visual()) {
      cells_ = io::encodeVtuCells(tetrahedra(), options_);
      options_.encodedCells = &cells_;
    }
  }

  void writeFrame(double t, int step, const Frame& fr) override {
    char num[32];
    std::snprintf(num, sizeof num, visual() ? "_%06d.vtp" : "_%06d.vtu", step);
    const std::string file = base() + num;
    std::vector<io::DataArray> pd, cd;
    for (const Field& f : fieldsOf(fr)) {
      if (f.onCells) cd.push_back({f.name, 1, std::vector<double>(f.cells.data(), f.cells.data() + f.cells.size())});
      else pd.push_back({f.name, 3, std::vector<double>(f.points.data(), f.points.data() + f.points.size())});
    }
    if (visual()) io::writeVtp(file, fr.x, triangles(), false, pd, options_);
    else io::writeVtu(file, fr.x, tetrahedra(), pd, cd, options_);
    written_.push_back({t, std::filesystem::path(file).filename().string()});
    // The index is rewritten each time so that an interrupted run still opens in ParaView.
    io::writePvd(base() + ".pvd", written_);
  }

  io::VtuWriteOptions options_;
  std::string cells_;  // the encoded <Cells> of every volume frame
  std::vector<std::pair<double, std::string>> written_;  // by the writer
};

}  // namespace

void registerVTKExporter(Registry& r) {
  ComponentSpec s;
  s.name = "VTKExporter";
  s.category = "output";
  s.doc = "Writes the node's MechanicalObject (with the tetrahedra of its FEM force field) as a .vtu series "
          "and a .pvd index for ParaView. Files are <filename>_<step>.vtu in the output folder (--out). In a node "
          "with an OglModel/VisualModel and no MechanicalObject (a visual child node; `mstate` not set), writes that "
          "surface instead: <filename>_<step>.vtp with its triangles and the point field displacement. A run that "
          "diverges between export steps still writes its last good step. Each frame is a file of its own, complete "
          "as soon as it is written; ExodusExporter writes a far smaller series (the mesh once).";
  s.add(AttrSpec::string("filename").help("base name of the files (default: the component's name; beside a visual model, that model's name); an extension .vtk, .vtu or .vtp is dropped"));
  SeriesExporter::addCommonAttributes(s);
  s.add(AttrSpec::boolean("compress").def("true").help(
      "zlib-compress the arrays (vtkZLibDataCompressor, read by ParaView and VTK) with Int32 connectivity; "
      "false: plain base64 binary with Int64 connectivity"));
  s.add(AttrSpec::boolean("XMLformat").def("true").help("accepted for SOFA compatibility; output is always VTK XML (.vtu, .vtp for a visual surface)"));
  s.add(AttrSpec::string("position").def("").help("accepted for SOFA compatibility; the node's positions are written"));
  s.add(AttrSpec::boolean("edges").def("false").help("accepted for SOFA compatibility"));
  s.add(AttrSpec::boolean("quads").def("false").help("accepted for SOFA compatibility; a visual surface is written with its triangles"));
  s.add(AttrSpec::boolean("triangles").def("false").help("accepted for SOFA compatibility; a visual surface is written with its triangles"));
  s.add(AttrSpec::boolean("tetras").def("true").help("accepted for SOFA compatibility; tetrahedra are written"));
  s.add(AttrSpec::boolean("overwrite").def("false").help("accepted for SOFA compatibility"));
  s.factory = [](BuildContext& c) { return std::make_unique<VTKExporter>(c); };
  r.add(std::move(s));
}

}  // namespace viscera
