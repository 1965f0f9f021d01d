#include "core/Schema.h"

#include <sstream>

namespace viscera {

const char* kindName(AttrKind k) {
  switch (k) {
    case AttrKind::Real: return "real";
    case AttrKind::Int: return "int";
    case AttrKind::Bool: return "bool";
    case AttrKind::String: return "string";
    case AttrKind::Enum: return "enum";
    case AttrKind::Reals: return "real list";
    case AttrKind::Ints: return "int list";
    case AttrKind::Link: return "link";
    case AttrKind::File: return "file";
  }
  return "?";
}

std::string AttrSpec::rangeText() const {
  if (!lo && !hi) return "";
  std::ostringstream s;
  s << (lo && !loOpen ? "[" : "(");
  if (lo) s << *lo; else s << "-inf";
  s << ", ";
  if (hi) s << *hi; else s << "inf";
  s << (hi && !hiOpen ? "]" : ")");
  return s.str();
}

const AttrSpec* ComponentSpec::find(const std::string& attr) const {
  for (const auto& a : attrs) {
    if (a.name == attr) return &a;
    for (const auto& al : a.aliases)
      if (al == attr) return &a;
  }
  return nullptr;
}

bool isCosmeticAttribute(const std::string& name) {
  static const char* exact[] = {"printLog", "listening", "tags", "bbox", "componentState",
                                "computeGlobalMatrix", "showIndices", "showIndicesScale",
                                "showObject", "showObjectScale", "showColor", "color",
                                "createTriangleArray", "checkTopology", "checkConnexity",
                                // SOFA: texture seams and materials of OBJ files, sub-elements a
                                // loader lists for drawing, stress and bounding-box outputs, threads
                                "handleSeams", "loadMaterial", "createSubelements", "computeVonMisesStress",
                                "computeBoundingBox", "multiThreadSimulation", "multithreading",
                                // SOFA: how element loops are run (sequenced or parallel)
                                "computeForceStrategy", "computeForceDerivStrategy",
                                // SOFA: the matrix storage a linear solver uses, and its threading
                                "linearSystem", "parallelInverseProduct",
                                // SOFA: a node's old ordering hint, and a solver's residual printout
                                "depend", "computeResidual",
                                // SOFA: element lists an ROI or a grid also outputs, drawing switches
                                "computeTriangles", "computeEdges", "computeTetrahedra", "computeHexahedra",
                                "computeQuads", "computeHexaList", "computeQuadList", "computeTriangleList",
                                "computeEdgeList", "computePointList", "isVisible",
                                // SOFA: OpenGL blending of a visual model
                                "blendEquation", "sourceBlendingFactor", "destinationBlendingFactor", "sfactor",
                                "dfactor", "primitiveType", "alphaBlend", "depthTest", "writeZTransparent", "springColor",
                                // SOFA: assemble the element matrices into one global matrix (same forces)
                                "assembling"};
  for (const char* e : exact)
    if (name == e) return true;
  return name.rfind("draw", 0) == 0 || name.rfind("show", 0) == 0;
}

}  // namespace viscera
