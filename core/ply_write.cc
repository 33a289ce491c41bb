// Writing PLY files (core/ply.h).

#include <cassert>
#include <cstdio>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>

#include "core/atomic_file.h"
#include "core/ply.h"
#include "core/ply_codec.h"
#include "core/ply_header.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

using ply_internal::AppendAsciiValue;
using ply_internal::Convert;
using ply_internal::Dispatch;
using ply_internal::FormatName;
using ply_internal::NeedsSwap;
using ply_internal::Store;

constexpr std::string_view kHeatwaveComment = "written by heatwave";

// Encodes one column of a table of fixed-size rows.
template <typename T, bool kSwap>
void EncodeColumn(const double* in, size_t n, char* first, size_t stride) {
  for (size_t i = 0; i < n; ++i) Store<T, kSwap>(Convert<T>(in[i]), first + i * stride);
}

}  // namespace

std::string SerializePly(const PlyMesh& mesh, PlyFormat format) {
  const std::string problem = mesh.Check();
  if (!problem.empty()) std::fprintf(stderr, "SerializePly: invalid mesh: %s\n", problem.c_str());
  assert(problem.empty() && "SerializePly: invalid mesh (see PlyMesh::Check)");

  const size_t n = mesh.NumVertices();
  const size_t num_faces = mesh.faces.size();
  std::string header =
      "ply\nformat " + FormatName(format) + " 1.0\ncomment " + std::string(kHeatwaveComment) + "\n";
  for (const std::string& comment : mesh.comments) {
    if (comment != kHeatwaveComment) header += "comment " + comment + "\n";
  }
  header += "element vertex " + std::to_string(n) + "\n";
  for (const PlyProperty& p : mesh.vertex_properties) {
    header += "property " + std::string(PlyTypeName(p.type)) + " " + p.name + "\n";
  }
  header += "element face " + std::to_string(num_faces) + "\n";
  header += "property list uchar int vertex_indices\nend_header\n";

  if (format == PlyFormat::kAscii) {
    std::string out = std::move(header);
    out.reserve(out.size() + n * mesh.vertex_properties.size() * 12 + num_faces * 24);
    for (size_t i = 0; i < n; ++i) {
      for (size_t j = 0; j < mesh.vertex_properties.size(); ++j) {
        if (j > 0) out += ' ';
        AppendAsciiValue(mesh.vertex_properties[j].type, mesh.vertex_properties[j].values[i], &out);
      }
      out += '\n';
    }
    for (const Eigen::Vector3i& face : mesh.faces) {
      out += '3';
      for (int k = 0; k < 3; ++k) {
        out += ' ';
        AppendAsciiValue(PlyType::kInt32, face[k], &out);
      }
      out += '\n';
    }
    return out;
  }

  const bool swap = NeedsSwap(format);
  size_t stride = 0;
  for (const PlyProperty& p : mesh.vertex_properties) stride += PlyTypeSize(p.type);
  constexpr size_t kFaceBytes = 1 + 3 * sizeof(int32_t);
  std::string out(header.size() + n * stride + num_faces * kFaceBytes, '\0');
  std::memcpy(out.data(), header.data(), header.size());
  char* const vertex_data = out.data() + header.size();
  size_t offset = 0;
  for (const PlyProperty& p : mesh.vertex_properties) {
    Dispatch(p.type, [&](auto tag) {
      using T = decltype(tag);
      if (swap) {
        EncodeColumn<T, true>(p.values.data(), n, vertex_data + offset, stride);
      } else {
        EncodeColumn<T, false>(p.values.data(), n, vertex_data + offset, stride);
      }
    });
    offset += PlyTypeSize(p.type);
  }
  char* face_data = vertex_data + n * stride;
  for (const Eigen::Vector3i& face : mesh.faces) {
    *face_data++ = 3;
    for (int k = 0; k < 3; ++k) {
      if (swap) {
        Store<int32_t, true>(face[k], face_data);
      } else {
        Store<int32_t, false>(face[k], face_data);
      }
      face_data += sizeof(int32_t);
    }
  }
  assert(face_data == out.data() + out.size());
  return out;
}

void WritePly(const fs::path& path, const PlyMesh& mesh, PlyFormat format) {
  WriteFileAtomically(path, SerializePly(mesh, format));
}

}  // namespace hw::core
