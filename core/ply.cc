// PlyMesh (core/ply.h). Reading is in core/ply_read.cc, writing in core/ply_write.cc, the
// header in core/ply_header.cc, types and number text in core/ply_codec.cc.

#include "core/ply.h"

#include <algorithm>
#include <cassert>
#include <climits>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "core/ply_codec.h"

namespace hw::core {

namespace {

using ply_internal::FirstRepeated;
using ply_internal::IsValidName;
using ply_internal::kTypes;
using ply_internal::Quoted;

// Sets the properties `names` to `columns` (replacing or adding them; new ones go to the
// front when `at_front`), asserting the size matches the properties not being set.
void SetColumns(PlyMesh& mesh, const std::vector<std::string_view>& names,
                std::vector<std::vector<double>> columns, PlyType type, bool at_front) {
  assert(names.size() == columns.size() && !names.empty());
  const size_t n = columns[0].size();
  for (const auto& column : columns) assert(column.size() == n);
  for (const PlyProperty& p : mesh.vertex_properties) {
    if (std::find(names.begin(), names.end(), p.name) == names.end()) {
      assert(p.values.size() == n && "property size differs from the mesh's vertex count");
    }
  }
  size_t insert_at = 0;
  for (size_t k = 0; k < names.size(); ++k) {
    assert(IsValidName(names[k]));
    if (PlyProperty* existing = mesh.Find(names[k])) {
      existing->type = type;
      existing->values = std::move(columns[k]);
      continue;
    }
    PlyProperty property{std::string(names[k]), type, std::move(columns[k])};
    if (at_front) {
      mesh.vertex_properties.insert(mesh.vertex_properties.begin() + insert_at++,
                                    std::move(property));
    } else {
      mesh.vertex_properties.push_back(std::move(property));
    }
  }
}

std::vector<Eigen::Vector3d> GetTriple(const PlyMesh& mesh, std::string_view a, std::string_view b,
                                       std::string_view c) {
  const std::vector<double>& xs = mesh.Get(a).values;
  const std::vector<double>& ys = mesh.Get(b).values;
  const std::vector<double>& zs = mesh.Get(c).values;
  assert(xs.size() == ys.size() && xs.size() == zs.size());
  std::vector<Eigen::Vector3d> out(xs.size());
  for (size_t i = 0; i < xs.size(); ++i) out[i] = Eigen::Vector3d(xs[i], ys[i], zs[i]);
  return out;
}

void SetTriple(PlyMesh& mesh, std::string_view a, std::string_view b, std::string_view c,
               const std::vector<Eigen::Vector3d>& data, PlyType type, bool at_front) {
  std::vector<std::vector<double>> columns(3, std::vector<double>(data.size()));
  for (size_t i = 0; i < data.size(); ++i) {
    for (int k = 0; k < 3; ++k) columns[k][i] = data[i][k];
  }
  SetColumns(mesh, {a, b, c}, std::move(columns), type, at_front);
}

uint8_t ColorByte(const PlyProperty& property, size_t i) {
  double v = property.values[i];
  if (!PlyTypeIsInteger(property.type)) v *= 255.0;
  if (std::isnan(v)) return 0;
  return static_cast<uint8_t>(std::clamp(std::round(v), 0.0, 255.0));
}

}  // namespace

size_t PlyMesh::NumVertices() const {
  return vertex_properties.empty() ? 0 : vertex_properties.front().values.size();
}

const PlyProperty* PlyMesh::Find(std::string_view name) const {
  for (const PlyProperty& p : vertex_properties) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

PlyProperty* PlyMesh::Find(std::string_view name) {
  for (PlyProperty& p : vertex_properties) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

const PlyProperty& PlyMesh::Get(std::string_view name) const {
  const PlyProperty* p = Find(name);
  if (p == nullptr) {
    std::fprintf(stderr, "PlyMesh::Get: no property '%.*s'\n", static_cast<int>(name.size()),
                 name.data());
  }
  assert(p != nullptr);
  return *p;
}

PlyProperty& PlyMesh::Get(std::string_view name) {
  return const_cast<PlyProperty&>(std::as_const(*this).Get(name));
}

void PlyMesh::AddProperty(std::string name, PlyType type, std::vector<double> values) {
  assert(IsValidName(name));
  assert(Find(name) == nullptr && "AddProperty: name already used");
  assert((vertex_properties.empty() || values.size() == NumVertices()) &&
         "AddProperty: size differs from the mesh's vertex count");
  vertex_properties.push_back(PlyProperty{std::move(name), type, std::move(values)});
}

void PlyMesh::SetProperty(std::string name, PlyType type, std::vector<double> values) {
  std::vector<std::vector<double>> columns;
  columns.push_back(std::move(values));
  SetColumns(*this, {name}, std::move(columns), type, /*at_front=*/false);
}

bool PlyMesh::RemoveProperty(std::string_view name) {
  const auto it = std::find_if(vertex_properties.begin(), vertex_properties.end(),
                               [&](const PlyProperty& p) { return p.name == name; });
  if (it == vertex_properties.end()) return false;
  vertex_properties.erase(it);
  return true;
}

bool PlyMesh::HasPositions() const { return Find("x") && Find("y") && Find("z"); }

std::vector<Eigen::Vector3d> PlyMesh::Positions() const { return GetTriple(*this, "x", "y", "z"); }

void PlyMesh::SetPositions(const std::vector<Eigen::Vector3d>& positions, PlyType type) {
  SetTriple(*this, "x", "y", "z", positions, type, /*at_front=*/true);
}

bool PlyMesh::HasNormals() const { return Find("nx") && Find("ny") && Find("nz"); }

std::vector<Eigen::Vector3d> PlyMesh::Normals() const { return GetTriple(*this, "nx", "ny", "nz"); }

void PlyMesh::SetNormals(const std::vector<Eigen::Vector3d>& normals, PlyType type) {
  SetTriple(*this, "nx", "ny", "nz", normals, type, /*at_front=*/false);
}

bool PlyMesh::HasColors() const { return Find("red") && Find("green") && Find("blue"); }

std::vector<Rgb8> PlyMesh::Colors() const {
  const PlyProperty& r = Get("red");
  const PlyProperty& g = Get("green");
  const PlyProperty& b = Get("blue");
  std::vector<Rgb8> out(r.values.size());
  for (size_t i = 0; i < out.size(); ++i) {
    out[i] = Rgb8(ColorByte(r, i), ColorByte(g, i), ColorByte(b, i));
  }
  return out;
}

std::vector<Rgba8> PlyMesh::ColorsWithAlpha() const {
  const std::vector<Rgb8> rgb = Colors();
  const PlyProperty* a = Find("alpha");
  std::vector<Rgba8> out(rgb.size());
  for (size_t i = 0; i < out.size(); ++i) {
    out[i] = Rgba8(rgb[i][0], rgb[i][1], rgb[i][2], a ? ColorByte(*a, i) : uint8_t{255});
  }
  return out;
}

void PlyMesh::SetColors(const std::vector<Rgb8>& colors) {
  RemoveProperty("alpha");
  std::vector<std::vector<double>> columns(3, std::vector<double>(colors.size()));
  for (size_t i = 0; i < colors.size(); ++i) {
    for (int k = 0; k < 3; ++k) columns[k][i] = colors[i][k];
  }
  SetColumns(*this, {"red", "green", "blue"}, std::move(columns), PlyType::kUInt8, false);
}

void PlyMesh::SetColorsWithAlpha(const std::vector<Rgba8>& colors) {
  std::vector<std::vector<double>> columns(4, std::vector<double>(colors.size()));
  for (size_t i = 0; i < colors.size(); ++i) {
    for (int k = 0; k < 4; ++k) columns[k][i] = colors[i][k];
  }
  SetColumns(*this, {"red", "green", "blue", "alpha"}, std::move(columns), PlyType::kUInt8, false);
}

std::string PlyMesh::Check() const {
  const size_t n = NumVertices();
  // Found by sorting the names once: comparing each with all before it took a minute for
  // 100k properties. Reported at its place in the loop, so the first problem in property
  // order is the one returned, whatever its kind.
  const size_t repeated = FirstRepeated(vertex_properties.size(), [&](size_t j) {
    return std::string_view(vertex_properties[j].name);
  });
  for (size_t j = 0; j < vertex_properties.size(); ++j) {
    const PlyProperty& p = vertex_properties[j];
    if (!IsValidName(p.name)) return "property " + Quoted(p.name) + ": invalid PLY name";
    if (static_cast<size_t>(p.type) >= kTypes.size()) return "property " + p.name + ": bad type";
    if (p.values.size() != n) {
      return "property " + p.name + " has " + std::to_string(p.values.size()) +
             " values, property " + vertex_properties[0].name + " has " + std::to_string(n);
    }
    if (j == repeated) return "duplicate property " + p.name;
  }
  if (n > static_cast<size_t>(INT_MAX)) return std::to_string(n) + " vertices, more than INT_MAX";
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      if (faces[f][k] < 0 || static_cast<size_t>(faces[f][k]) >= n) {
        return "face " + std::to_string(f) + ": vertex index " + std::to_string(faces[f][k]) +
               " out of range (" + std::to_string(n) + " vertices)";
      }
    }
  }
  for (const std::string& comment : comments) {
    if (comment.find_first_of("\r\n") != std::string::npos) {
      return "comment " + Quoted(comment) + " contains a line break";
    }
  }
  return "";
}

}  // namespace hw::core
