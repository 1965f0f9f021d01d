#include "core/Component.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/Scene.h"
#include "core/Text.h"

namespace viscera {

Component::Component(BuildContext& ctx)
    : attrs_(std::move(ctx.attrs())), spec_(ctx.spec()), node_(ctx.node()), scene_(ctx.scene()) {
  name_ = ctx.name();
}

std::vector<double> Component::linkedReals(const std::string& attr) {
  const AttrValue& v = attrs_.get(attr);
  if (!v.link) return v.nums;
  std::string path, field;
  splitLink(v.text, path, field);
  std::string what = attrs_.component() + "." + attr;
  Component& src = scene_.resolve(*this, v.text, v.loc, what);
  scene_.initComponent(src);
  if (field.empty()) field = attr;
  FieldValue out;
  if (!src.field(field, out)) {
    // SOFA links one component's setting to another's ("@[-1].contactStiffness"): a numeric
    // attribute given as numbers in the scene serves as a field too.
    const auto& values = src.attrs().values();
    const auto it = values.find(field);
    if (it == values.end() || !it->second.set || it->second.link || it->second.nums.empty())
      throw Error(v.loc, what + ": '" + src.name() + "' (" + src.typeName() + ") has no field '" + field + "'");
    out.values = it->second.nums;
  }
  try {
    checkAttrNumbers(*v.spec, out.values);
  } catch (const std::invalid_argument& e) {
    throw Error(v.loc, what + ": linked value: " + e.what());
  }
  return out.values;
}

std::vector<int> Component::linkedInts(const std::string& attr) {
  std::vector<int> r;
  for (double d : linkedReals(attr)) {
    if (d != std::floor(d)) throw error(attr, "linked value is not an integer");
    // Checked before the conversion, which is undefined outside int's range.
    if (!(d >= std::numeric_limits<int>::min() && d <= std::numeric_limits<int>::max()))
      throw error(attr, "linked value " + formatNumber(d) + " is out of range for an integer");
    r.push_back(static_cast<int>(d));
  }
  return r;
}

Component* Component::linkedComponent(const std::string& attr) {
  const AttrValue& v = attrs_.get(attr);
  if (!v.set) return nullptr;
  Component& c = scene_.resolve(*this, v.text, v.loc, attrs_.component() + "." + attr);
  scene_.initComponent(c);
  return &c;
}

Node& Node::addChild(std::string name, SourceLoc loc) {
  children_.push_back(std::make_unique<Node>(std::move(name), this, std::move(loc)));
  return *children_.back();
}

Component& Node::addComponent(std::unique_ptr<Component> c) {
  components_.push_back(std::move(c));
  objects_.push_back({components_.back()->typeName(), components_.back().get()});
  return *components_.back();
}

std::string Node::path() const { return parent_ ? parent_->path() + "/" + name_ : "/" + name_; }

}  // namespace viscera
