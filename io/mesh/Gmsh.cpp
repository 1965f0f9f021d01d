// Gmsh .msh reader: legacy v1 ($NOD/$ELM), v2 and v4.0/v4.1 ASCII.
#include <algorithm>
#include <climits>
#include <string>
#include <unordered_map>

#include "core/Error.h"
#include "io/mesh/Mesh.h"
#include "io/mesh/MeshDetail.h"

namespace viscera::io {
namespace {

using detail::quoted;

const char* gmshTypeName(long long type) {
  switch (type) {
    case 1: return "2-node line";
    case 2: return "3-node triangle";
    case 3: return "4-node quadrangle";
    case 4: return "4-node tetrahedron";
    case 5: return "8-node hexahedron";
    case 6: return "6-node prism";
    case 7: return "5-node pyramid";
    case 8: return "3-node second-order line";
    case 9: return "6-node second-order triangle";
    case 10: return "9-node second-order quadrangle";
    case 11: return "10-node second-order tetrahedron";
    case 12: return "27-node second-order hexahedron";
    case 13: return "18-node second-order prism";
    case 14: return "14-node second-order pyramid";
    case 15: return "1-node point";
    case 16: return "8-node second-order quadrangle";
    case 17: return "20-node second-order hexahedron";
    case 18: return "15-node second-order prism";
    case 19: return "13-node second-order pyramid";
    default: return nullptr;
  }
}

// Node count of the types that are kept (tetrahedron, hexahedron, triangle, quadrangle) or
// skipped (point, line).
int knownNodeCount(long long type) {
  switch (type) {
    case 5: return 8;
    case 4: return 4;
    case 3: return 4;
    case 2: return 3;
    case 1: return 2;
    case 15: return 1;
    default: return 0;
  }
}

bool isKept(long long type) { return type == 2 || type == 3 || type == 4 || type == 5; }

std::string plural(long long n, const char* noun) { return std::to_string(n) + " " + noun + (n == 1 ? "" : "s"); }

class GmshReader {
 public:
  GmshReader(std::string_view text, const std::string& path) : in_(text, path) {}

  VolumeMesh read() {
    while (in_.nextNonBlank()) {
      const std::string_view head = in_.text();
      if (head.empty() || head[0] != '$')
        in_.fail("expected a section such as $Nodes or $Elements, found " + quoted(head));
      if (head == "$MeshFormat") {
        readFormat();
      } else if (head == "$NOD") {
        beginSection(nodesLine_, "$NOD");
        readNodesV1V2("$NOD", "$ENDNOD");
      } else if (head == "$ELM") {
        beginSection(elementsLine_, "$ELM");
        readElementsV1V2("$ELM", "$ENDELM", true);
      } else if (head == "$Nodes") {
        requireFormat("$Nodes");
        beginSection(nodesLine_, "$Nodes");
        if (version_ >= 4) readNodesV4(); else readNodesV1V2("$Nodes", "$EndNodes");
      } else if (head == "$Elements") {
        requireFormat("$Elements");
        beginSection(elementsLine_, "$Elements");
        if (version_ >= 4) readElementsV4(); else readElementsV1V2("$Elements", "$EndElements", false);
      } else {
        skipSection(std::string(head));  // $Entities, $PhysicalNames, $NodeData, ...: not needed
      }
    }
    if (nodesLine_ == 0) in_.fail(formatLine_ ? "missing $Nodes section" : "not a Gmsh mesh: no $MeshFormat or $NOD section");
    if (elementsLine_ == 0) in_.fail(std::string("missing ") + (version_ > 0 ? "$Elements" : "$ELM") + " section");
    return resolve();
  }

 private:
  struct Element {
    long long tag;
    int line;
    long long type;  // Gmsh's: 2 triangle, 3 quadrangle, 4 tetrahedron, 5 hexahedron
    int count;
    long long nodes[8];
  };

  void beginSection(int& seenLine, const char* name) {
    if (seenLine) in_.fail(std::string("second ") + name + " section (the first is on line " + std::to_string(seenLine) + ")");
    seenLine = in_.line();
  }

  void requireFormat(const char* section) {
    if (formatLine_ == 0) in_.fail(std::string(section) + " before $MeshFormat");
  }

  void readFormat() {
    if (formatLine_) in_.fail("second $MeshFormat section");
    formatLine_ = in_.line();
    if (!in_.nextNonBlank()) in_.fail("file ends inside $MeshFormat");
    const auto& t = in_.tokens();
    if (t.size() < 3) in_.fail("$MeshFormat needs 'version file-type data-size', found " + quoted(in_.text()));
    double version;
    if (!detail::parseReal(t[0], version)) in_.fail("expected a version number in $MeshFormat, found " + quoted(t[0]));
    const long long fileType = in_.intAt(1, "the file type in $MeshFormat");
    if (fileType == 1) in_.fail("binary .msh is not supported; save as ASCII");
    if (fileType != 0) in_.fail("unknown file type " + std::to_string(fileType) + " in $MeshFormat (0 is ASCII)");
    if (!(version >= 2 && version < 3) && !(version >= 4 && version < 5))
      in_.fail("Gmsh format version " + std::string(t[0]) + " is not supported (2.x, 4.0 and 4.1 are)");
    version_ = version;
    v41_ = version >= 4.05;
    expectEnd("$EndMeshFormat", "the format line");
  }

  // The next data line of a section; fails at end of file or at a '$' line, which both mean
  // the section holds fewer records than it declared.
  const std::vector<std::string_view>& record(const std::string& what, long long declared, long long done, const char* noun) {
    if (!in_.nextNonBlank())
      in_.fail("file ends inside " + what + " after " + std::to_string(done) + " of the " + plural(declared, noun) + " it declares");
    if (in_.text()[0] == '$')
      in_.fail(what + " declares " + plural(declared, noun) + " but only " + std::to_string(done) + " precede " + quoted(in_.text()));
    return in_.tokens();
  }

  void expectEnd(const char* end, const std::string& after) {
    if (!in_.nextNonBlank()) in_.fail(std::string("file ends before ") + end);
    if (in_.text() != end) in_.fail(std::string("expected ") + end + " after " + after + ", found " + quoted(in_.text()));
  }

  void skipSection(const std::string& head) {
    const std::string end = "$End" + head.substr(1);
    const int start = in_.line();
    while (in_.next())
      if (detail::equalsIgnoreCase(in_.text(), end)) return;
    in_.fail("file ends inside " + head + " (opened on line " + std::to_string(start) + "; no " + end + ")");
  }

  long long count(size_t i, const std::string& what) {
    const long long n = in_.intAt(i, what);
    if (n < 0 || n > INT_MAX) in_.fail(what + " must be between 0 and " + std::to_string(INT_MAX) + ", found " + std::to_string(n));
    return n;
  }

  void reserveNodes(long long n) {
    const size_t cap = static_cast<size_t>(std::min<long long>(n, 1 << 20));  // a bogus count must not allocate much
    tags_.reserve(cap);
    nodeLines_.reserve(cap);
    xyz_.reserve(3 * cap);
  }

  void addNode(long long tag, size_t firstCoord) {
    tags_.push_back(tag);
    nodeLines_.push_back(in_.line());
    for (size_t k = 0; k < 3; ++k) xyz_.push_back(in_.realAt(firstCoord + k, "a node coordinate"));
  }

  void readNodesV1V2(const char* section, const char* end) {
    if (!in_.nextNonBlank()) in_.fail(std::string("file ends inside ") + section);
    if (in_.tokens().size() != 1) in_.fail(std::string(section) + " must start with the number of nodes, found " + quoted(in_.text()));
    const long long n = count(0, "the number of nodes");
    reserveNodes(n);
    for (long long i = 0; i < n; ++i) {
      const auto& t = record(section, n, i, "node");
      if (t.size() != 4) in_.fail("a node line needs 4 values (tag x y z), found " + std::to_string(t.size()));
      addNode(in_.intAt(0, "the node tag"), 1);
    }
    expectEnd(end, plural(n, "node"));
  }

  void readNodesV4() {
    if (!in_.nextNonBlank()) in_.fail("file ends inside $Nodes");
    const size_t headerSize = v41_ ? 4 : 2;
    if (in_.tokens().size() != headerSize)
      in_.fail(std::string("the $Nodes header needs ") + (v41_ ? "4 values (blocks nodes minTag maxTag)" : "2 values (blocks nodes)") +
               ", found " + quoted(in_.text()));
    const int headerLine = in_.line();
    const long long blocks = count(0, "the number of node blocks"), total = count(1, "the number of nodes");
    reserveNodes(total);
    long long read = 0;
    for (long long b = 0; b < blocks; ++b) {
      const auto& h = record("$Nodes", blocks, b, "entity block");
      if (h.size() != 4) in_.fail("a node block header needs 4 values, found " + quoted(in_.text()));
      const long long dim = in_.intAt(v41_ ? 0 : 1, "the entity dimension");
      const bool parametric = in_.intAt(2, "the parametric flag") != 0;
      const long long n = count(3, "the number of nodes in the block");
      if (read + n > total)
        in_.fail("the $Nodes header (line " + std::to_string(headerLine) + ") declares " + plural(total, "node") +
                 " but the blocks hold more");
      const std::string what = "node block of line " + std::to_string(in_.line());
      const size_t coords = 3 + (parametric ? static_cast<size_t>(std::clamp<long long>(dim, 0, 3)) : 0);
      if (v41_) {
        // 4.1: all tags of the block, then all coordinates.
        long long tagsRead = 0;
        while (tagsRead < n) {
          const auto& t = record(what, n, tagsRead, "node tag");
          if (tagsRead + static_cast<long long>(t.size()) > n)
            in_.fail("the " + what + " declares " + plural(n, "node") + " but lists more tags");
          for (size_t k = 0; k < t.size(); ++k, ++tagsRead) {
            tags_.push_back(in_.intAt(k, "a node tag"));
            nodeLines_.push_back(in_.line());
          }
        }
        for (long long i = 0; i < n; ++i) {
          const auto& t = record(what, n, i, "coordinate line");
          if (t.size() != coords)
            in_.fail("a node coordinate line needs " + std::to_string(coords) + " values, found " + std::to_string(t.size()));
          for (size_t k = 0; k < 3; ++k) xyz_.push_back(in_.realAt(k, "a node coordinate"));
        }
      } else {
        for (long long i = 0; i < n; ++i) {
          const auto& t = record(what, n, i, "node");
          if (t.size() != coords + 1)
            in_.fail("a node line needs " + std::to_string(coords + 1) + " values (tag x y z" + (coords > 3 ? " u..." : "") +
                     "), found " + std::to_string(t.size()));
          addNode(in_.intAt(0, "the node tag"), 1);
        }
      }
      read += n;
    }
    if (read != total)
      detail::fail(in_.source(), headerLine,
                   "the $Nodes header declares " + plural(total, "node") + " but the blocks hold " + std::to_string(read));
    expectEnd("$EndNodes", plural(blocks, "node block"));
  }

  [[noreturn]] void unsupported(long long tag, long long type) {
    const char* name = gmshTypeName(type);
    in_.fail("element " + std::to_string(tag) + " has Gmsh type " + std::to_string(type) +
             (name ? std::string(" (") + name + ")" : "") +
             ", which is not supported: 4-node tetrahedra (type 4), 8-node hexahedra (5), 3-node triangles (2) and "
             "4-node quadrangles (3) are read; points and lines are skipped");
  }

  // Reads the element's node tags from tokens [first, first + nodes) and keeps it if wanted.
  void addElement(long long tag, long long type, size_t first) {
    const int n = knownNodeCount(type);
    Element e{tag, in_.line(), type, n, {}};
    for (int k = 0; k < n; ++k) e.nodes[k] = in_.intAt(first + k, "a node tag");
    if (!isKept(type)) return;
    elements_.push_back(e);
  }

  // v1 lines: number type physical elementary nodeCount nodes...; v2: number type tagCount tags... nodes...
  void readElementsV1V2(const char* section, const char* end, bool v1) {
    if (!in_.nextNonBlank()) in_.fail(std::string("file ends inside ") + section);
    if (in_.tokens().size() != 1)
      in_.fail(std::string(section) + " must start with the number of elements, found " + quoted(in_.text()));
    const long long n = count(0, "the number of elements");
    for (long long i = 0; i < n; ++i) {
      const auto& t = record(section, n, i, "element");
      if (t.size() < 3) in_.fail("an element line needs at least 3 values, found " + quoted(in_.text()));
      const long long tag = in_.intAt(0, "the element number"), type = in_.intAt(1, "the element type");
      const int nodes = knownNodeCount(type);
      if (nodes == 0) unsupported(tag, type);
      size_t first;
      if (v1) {
        if (t.size() < 5) in_.fail("an element line needs at least 5 values, found " + quoted(in_.text()));
        for (size_t k = 2; k < 4; ++k) in_.intAt(k, "a region number");
        const long long declared = in_.intAt(4, "the number of nodes");
        if (declared != nodes)
          in_.fail("element " + std::to_string(tag) + " of type " + std::to_string(type) + " declares " +
                   plural(declared, "node") + "; that type has " + std::to_string(nodes));
        first = 5;
      } else {
        const long long tagCount = in_.intAt(2, "the number of tags");
        if (tagCount < 0 || tagCount > static_cast<long long>(t.size()))
          in_.fail("element " + std::to_string(tag) + " declares " + std::to_string(tagCount) + " tags, but the line holds " +
                   std::to_string(t.size()) + " values");
        for (size_t k = 0; k < static_cast<size_t>(tagCount); ++k) in_.intAt(3 + k, "an element tag");
        first = 3 + static_cast<size_t>(tagCount);
      }
      if (t.size() != first + nodes)
        in_.fail("element " + std::to_string(tag) + " is a " + gmshTypeName(type) +
                 (v1 ? std::string() : " with " + plural(static_cast<long long>(first) - 3, "tag")) + ", so its line needs " +
                 std::to_string(first + nodes) + " values; found " + std::to_string(t.size()));
      addElement(tag, type, first);
    }
    expectEnd(end, plural(n, "element"));
  }

  void readElementsV4() {
    if (!in_.nextNonBlank()) in_.fail("file ends inside $Elements");
    const size_t headerSize = v41_ ? 4 : 2;
    if (in_.tokens().size() != headerSize)
      in_.fail(std::string("the $Elements header needs ") +
               (v41_ ? "4 values (blocks elements minTag maxTag)" : "2 values (blocks elements)") + ", found " + quoted(in_.text()));
    const int headerLine = in_.line();
    const long long blocks = count(0, "the number of element blocks"), total = count(1, "the number of elements");
    long long read = 0;
    for (long long b = 0; b < blocks; ++b) {
      const auto& h = record("$Elements", blocks, b, "entity block");
      if (h.size() != 4) in_.fail("an element block header needs 4 values, found " + quoted(in_.text()));
      const long long type = in_.intAt(2, "the element type");
      const long long n = count(3, "the number of elements in the block");
      const int nodes = knownNodeCount(type);
      if (nodes == 0 && n > 0) {
        // Name the first element of the block when there is one.
        const auto& t = record("element block", n, 0, "element");
        unsupported(t.empty() ? 0 : in_.intAt(0, "the element tag"), type);
      }
      if (read + n > total)
        in_.fail("the $Elements header (line " + std::to_string(headerLine) + ") declares " + plural(total, "element") +
                 " but the blocks hold more");
      const std::string what = "element block of line " + std::to_string(in_.line());
      for (long long i = 0; i < n; ++i) {
        const auto& t = record(what, n, i, "element");
        const long long tag = in_.intAt(0, "the element tag");
        if (t.size() != static_cast<size_t>(1 + nodes))
          in_.fail("element " + std::to_string(tag) + " is a " + gmshTypeName(type) + ", so its line needs " +
                   std::to_string(1 + nodes) + " values (tag and nodes); found " + std::to_string(t.size()));
        addElement(tag, type, 1);
      }
      read += n;
    }
    if (read != total)
      detail::fail(in_.source(), headerLine,
                   "the $Elements header declares " + plural(total, "element") + " but the blocks hold " + std::to_string(read));
    expectEnd("$EndElements", plural(blocks, "element block"));
  }

  // Maps node tags to 0-based indices and builds the mesh.
  VolumeMesh resolve() {
    const long long n = static_cast<long long>(tags_.size());
    // Tags are usually 1..n: a table beats hashing; fall back to a map for sparse tags.
    long long lo = LLONG_MAX, hi = LLONG_MIN;
    for (long long t : tags_) lo = std::min(lo, t), hi = std::max(hi, t);
    const bool dense = n > 0 && lo >= 0 && hi <= 2 * n + 64;
    std::vector<int> table;
    std::unordered_map<long long, int> map;
    if (dense) table.assign(static_cast<size_t>(hi + 1), -1); else map.reserve(static_cast<size_t>(n));
    for (long long i = 0; i < n; ++i) {
      const long long tag = tags_[i];
      int& slot = dense ? table[static_cast<size_t>(tag)] : map.try_emplace(tag, -1).first->second;
      if (slot >= 0)
        detail::fail(in_.source(), nodeLines_[i],
                     "node " + std::to_string(tag) + " is defined twice (first on line " + std::to_string(nodeLines_[slot]) + ")");
      slot = static_cast<int>(i);
    }
    auto lookup = [&](long long tag) -> int {
      if (dense) return tag >= 0 && tag <= hi ? table[static_cast<size_t>(tag)] : -1;
      auto it = map.find(tag);
      return it == map.end() ? -1 : it->second;
    };

    detail::MeshBuilder mesh;
    mesh.xyz = std::move(xyz_);
    for (const Element& e : elements_) {
      auto& out = e.type == 4 ? mesh.tets : e.type == 5 ? mesh.hexahedra : e.type == 3 ? mesh.quads : mesh.triangles;
      for (int k = 0; k < e.count; ++k) {
        const int index = lookup(e.nodes[k]);
        if (index < 0)
          detail::fail(in_.source(), e.line,
                       "element " + std::to_string(e.tag) + " refers to node " + std::to_string(e.nodes[k]) + ", but the file has " +
                           plural(n, "node") + " and none with that tag");
        out.push_back(index);
      }
    }
    return mesh.finish();
  }

  detail::LineCursor in_;
  double version_ = 0;  // 0: legacy v1 (no $MeshFormat)
  bool v41_ = false;
  int formatLine_ = 0, nodesLine_ = 0, elementsLine_ = 0;
  std::vector<long long> tags_;
  std::vector<int> nodeLines_;
  std::vector<double> xyz_;
  std::vector<Element> elements_;
};

}  // namespace

VolumeMesh readGmsh(const std::string& path) {
  const std::string text = detail::readWholeFile(path);
  return GmshReader(text, path).read();
}

}  // namespace viscera::io
