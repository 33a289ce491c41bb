#pragma once

// PLY (Stanford polygon file) reading and writing of triangle meshes and point clouds with
// arbitrary per-vertex scalar properties, in ASCII and binary (little- and big-endian).
// Files written here open in MeshLab and CloudCompare; files those write are read here.
//
// Typical use:
//   PlyMesh mesh;
//   mesh.SetPositions(points_in_world);                        // x y z, float
//   mesh.AddProperty("temperature_c", PlyType::kFloat32, temperature_c);
//   mesh.faces = triangles;
//   WritePly(out / "model.ply", mesh);
//   ...
//   const PlyMesh read = ReadPly(path);
//   const std::vector<Eigen::Vector3d> points = read.Positions();
//   const std::vector<double>& temperature_c = read.Get("temperature_c").values;

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace hw::core {

// The eight PLY scalar types.
enum class PlyType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64 };

// On-disk encodings. Binary little-endian is the default: compact, fast, and what MeshLab
// and CloudCompare write themselves.
enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

// Name written in headers: char uchar short ushort int uint float double.
std::string_view PlyTypeName(PlyType type);
// Parses a type name: the classic names above and the aliases int8 uint8 int16 uint16 int32
// uint32 float32 float64. nullopt for anything else.
std::optional<PlyType> ParsePlyType(std::string_view name);
// Size of one value on disk, bytes.
size_t PlyTypeSize(PlyType type);
bool PlyTypeIsInteger(PlyType type);
// `value` converted to what `type` stores, as written to a file: integer types round to
// nearest and saturate to the type's range (NaN becomes 0); float rounds to the nearest
// float (overflowing to +-inf); double is unchanged.
double PlyRepresentable(PlyType type, double value);

// One per-vertex property. Values are held as double, which is exact for every PLY scalar
// type; they are written back in `type` (converted as PlyRepresentable says).
struct PlyProperty {
  std::string name;
  PlyType type = PlyType::kFloat32;
  std::vector<double> values;  // one per vertex
};

// 8-bit colours, as PLY's red green blue [alpha] uchar properties.
using Rgb8 = Eigen::Matrix<std::uint8_t, 3, 1>;
using Rgba8 = Eigen::Matrix<std::uint8_t, 4, 1>;

// A triangle mesh (or, with no faces, a point cloud) with per-vertex properties.
// Properties are kept and written in order; names are unique. Conventional names:
// x y z (position), nx ny nz (normal), red green blue alpha (colour, uchar); heatwave adds
// temperature_c (°C), emissivity, confidence.
struct PlyMesh {
  std::vector<PlyProperty> vertex_properties;
  // Triangles as 0-based vertex indices, counter-clockwise seen from outside (PLY and
  // MeshLab convention). Polygons read from files are fan-triangulated.
  std::vector<Eigen::Vector3i> faces;
  // Header comments, without the "comment " keyword. On write, "written by heatwave" comes
  // first and these follow; on read, every comment line of the file is kept here.
  std::vector<std::string> comments;

  // Number of values of the first property; 0 without properties.
  size_t NumVertices() const;

  // The property called `name`, or nullptr. A linear search (a mesh has a handful of
  // properties; AddProperty, which asserts the name is new, is one too).
  const PlyProperty* Find(std::string_view name) const;
  PlyProperty* Find(std::string_view name);
  // The property called `name`; asserts that it exists (use Find when it may not).
  const PlyProperty& Get(std::string_view name) const;
  PlyProperty& Get(std::string_view name);

  // Appends a property. Asserts that `name` is new and a valid PLY name (non-empty, no
  // whitespace or control characters) and that values.size() equals NumVertices() when other
  // properties exist.
  void AddProperty(std::string name, PlyType type, std::vector<double> values);
  // Replaces the type and values of an existing property, or appends a new one; same
  // asserts on the size.
  void SetProperty(std::string name, PlyType type, std::vector<double> values);
  // Removes a property if present; returns whether it was.
  bool RemoveProperty(std::string_view name);

  // Positions from x y z (units as written, metres in heatwave). Asserts they exist.
  bool HasPositions() const;
  std::vector<Eigen::Vector3d> Positions() const;
  // Sets x y z (put first when new). Asserts the size matches the other properties.
  void SetPositions(const std::vector<Eigen::Vector3d>& positions,
                    PlyType type = PlyType::kFloat32);

  // Normals from nx ny nz, as stored (not renormalised). Asserts they exist.
  bool HasNormals() const;
  std::vector<Eigen::Vector3d> Normals() const;
  void SetNormals(const std::vector<Eigen::Vector3d>& normals, PlyType type = PlyType::kFloat32);

  // Colours from red green blue (and alpha, 255 when absent). Integer properties are
  // rounded and clamped to 0..255; float and double ones are taken as 0..1 (the convention
  // of writers that store float colour) and scaled by 255. Asserts red green blue exist.
  bool HasColors() const;
  std::vector<Rgb8> Colors() const;
  std::vector<Rgba8> ColorsWithAlpha() const;
  // Sets red green blue (uchar; removing any alpha), or red green blue alpha. (Two names,
  // not two overloads, so that SetColors({{255, 0, 0}, ...}) is not ambiguous.)
  void SetColors(const std::vector<Rgb8>& colors);
  void SetColorsWithAlpha(const std::vector<Rgba8>& colors);

  // "" if the mesh can be written, else what is wrong: property names empty, duplicated or
  // containing whitespace or control characters; properties of different lengths; a face index
  // outside [0, NumVertices()); a comment containing a line break; more than INT_MAX vertices.
  // The first problem in property order is the one named. O(n log n) in the number of
  // properties (repeated names are found by sorting), linear in vertices and faces.
  std::string Check() const;
};

// Reads a PLY file. Vertex properties that are scalars are kept (list properties of vertices
// and every element other than vertex and face are skipped, in every format); the face
// element needs a list property vertex_indices (or vertex_index) of integer counts and
// indices, any other face properties are skipped; polygons are fan-triangulated.
// Throws InputError naming the file and the problem, e.g. "line 7: unknown property type
// 'flaot'", "face 12: vertex index 5000 out of range (4000 vertices)", "truncated: expected
// 240000 bytes of vertex data, got 1000". Counts that the file is too short to hold are
// rejected before anything is allocated; bytes (or non-blank lines) after the last element
// are an error too, as they mean wrong counts. Vertex and face numbers in messages are
// 0-based; line numbers count from the "ply" line as 1.
// Limits, so that no file can make reading slow or large beyond its size: files up to
// kMaxMeshFileBytes (core/atomic_file.h); at most INT_MAX vertices; repeated element or
// property names are found in O(n log n) for n names. Memory is the file's bytes plus the
// mesh, with no temporary copies: 8 bytes per vertex value and 12 per triangle (so 3x the
// file for int indices, 6x for ushort and for ASCII, 12x for uchar indices, 8x for vertex
// data of only 1-byte values), plus a few times the header's size for its names
// (64 bytes per vertex property kept, 32 per comment).
PlyMesh ReadPly(const std::filesystem::path& path);
// Same, from the bytes of a file; `path_for_errors` only names it in messages.
PlyMesh ParsePly(std::string_view data, const std::filesystem::path& path_for_errors);

// Writes `mesh` atomically (core/atomic_file.h): header with "comment written by heatwave"
// (then mesh.comments, minus any copy of that one), element vertex with the properties in
// order, element face with "property list uchar int vertex_indices" ("element face 0" for a
// point cloud, as MeshLab writes). ASCII writes the shortest text that reads back to the
// same value. Asserts mesh.Check() is empty (a bad mesh is a bug); throws
// OutputError when the file cannot be written.
void WritePly(const std::filesystem::path& path, const PlyMesh& mesh,
              PlyFormat format = PlyFormat::kBinaryLittleEndian);
// The bytes WritePly writes.
std::string SerializePly(const PlyMesh& mesh, PlyFormat format = PlyFormat::kBinaryLittleEndian);

}  // namespace hw::core
