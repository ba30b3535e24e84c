// glTF 2.0 (.gltf, .glb) input through assimp (Debian's libassimp-dev): the nodes a scene names,
// with their transforms, as one polygon soup. Not a CGAL translation unit.

#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/Importer.hpp>

#include <Eigen/Core>
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "fsm/builder/mesh_io.hpp"
#include "fsm/error.hpp"

namespace fsm::build {

namespace {

using json = nlohmann::json;

std::uint32_t le32(const std::string& b, std::size_t at) {
  return std::uint32_t(std::uint8_t(b[at])) | std::uint32_t(std::uint8_t(b[at + 1])) << 8 |
         std::uint32_t(std::uint8_t(b[at + 2])) << 16 |
         std::uint32_t(std::uint8_t(b[at + 3])) << 24;
}

// The glTF's JSON: the whole file (.gltf) or the GLB's first chunk (checked against the bytes).
json gltf_json(const std::string& bytes, bool binary, const std::string& path) {
  std::string text;
  if (binary) {
    if (bytes.size() < 20 || bytes.compare(0, 4, "glTF") != 0)
      throw Error(path, "", "not a GLB file (no 'glTF' magic, or shorter than the 20-byte header)");
    if (le32(bytes, 4) != 2)
      throw Error(path, "", "GLB version " + std::to_string(le32(bytes, 4)) + " (only 2 is read)");
    const std::uint64_t chunk = le32(bytes, 12);
    if (bytes.compare(16, 4, "JSON") != 0 || chunk > bytes.size() - 20)
      throw Error(path, "", "the GLB's first chunk is not a JSON chunk inside the file");
    text = bytes.substr(20, std::size_t(chunk));
  } else {
    text = bytes;
  }
  json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) throw Error(path, "", "the glTF's JSON is malformed");
  return j;
}

// Required extensions that change how geometry is stored and that assimp 5.2 does not decode are
// refused by name (assimp would read garbage or nothing). Draco is decoded (Debian builds assimp
// with it); material and lighting extensions do not touch the geometry.
void check_required_extensions(const json& j, const std::string& path) {
  if (!j.contains("extensionsRequired")) return;
  const json& req = j["extensionsRequired"];
  if (!req.is_array()) throw Error(path, "", "'extensionsRequired' is not a list");
  for (const json& e : req) {
    const std::string name = e.is_string() ? e.get<std::string>() : std::string("?");
    const bool ok = name == "KHR_draco_mesh_compression" || name.rfind("KHR_materials_", 0) == 0 ||
                    name == "KHR_texture_transform" || name == "KHR_lights_punctual";
    if (!ok)
      throw Error(path, "",
                  "requires the glTF extension '" + name +
                      "', which this build cannot read (supported: KHR_draco_mesh_compression and "
                      "material extensions); export the mesh without it");
  }
}

Eigen::Matrix4d to_eigen(const aiMatrix4x4& m) {
  Eigen::Matrix4d e;
  e << m.a1, m.a2, m.a3, m.a4, m.b1, m.b2, m.b3, m.b4, m.c1, m.c2, m.c3, m.c4, m.d1, m.d2, m.d3,
      m.d4;
  return e;
}

struct Placed {
  const aiNode* node;
  Eigen::Matrix4d world;  // double: the file's float transforms composed without rounding
};

void collect(const aiNode* n, const Eigen::Matrix4d& parent, std::vector<Placed>& all) {
  const Eigen::Matrix4d world = parent * to_eigen(n->mTransformation);
  all.push_back({n, world});
  for (unsigned c = 0; c < n->mNumChildren; ++c) collect(n->mChildren[c], world, all);
}

bool inside(const aiNode* n, const aiNode* ancestor) {
  for (; n != nullptr; n = n->mParent)
    if (n == ancestor) return true;
  return false;
}

}  // namespace

PolygonSoup read_gltf(const std::string& bytes, const std::string& path,
                      const std::vector<std::string>& nodes) {
  std::string ext = path.size() >= 4 ? path.substr(path.size() - 4) : std::string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  const bool binary = ext == ".glb";
  const json j = gltf_json(bytes, binary, path);
  check_required_extensions(j, path);
  if (!j.contains("meshes") || !j["meshes"].is_array() || j["meshes"].empty())
    throw Error(path, "", "the glTF holds no mesh");

  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, aiProcess_ValidateDataStructure);
  if (scene == nullptr || scene->mRootNode == nullptr)
    throw Error(path, "", std::string("cannot read the glTF: ") + importer.GetErrorString());

  std::vector<Placed> all;
  collect(scene->mRootNode, Eigen::Matrix4d::Identity(), all);
  // The subtrees to take: the named nodes (every node of that name), or the whole scene.
  std::vector<const Placed*> roots;
  if (nodes.empty()) {
    roots.push_back(&all.front());
  } else {
    for (const std::string& name : nodes) {
      const std::size_t before = roots.size();
      for (const Placed& p : all)
        if (name == p.node->mName.C_Str()) roots.push_back(&p);
      if (roots.size() == before) {
        std::string names;
        for (const Placed& p : all)
          if (p.node != scene->mRootNode && p.node->mName.length > 0)
            names += (names.empty() ? "'" : ", '") + std::string(p.node->mName.C_Str()) + "'";
        throw Error(path, "node '" + name + "'",
                    "no such node; the file has " + (names.empty() ? "no named node" : names));
      }
    }
  }

  PolygonSoup soup;
  std::set<const aiNode*> taken;
  for (const Placed& p : all) {
    const Placed* root = nullptr;
    for (const Placed* r : roots)
      if (inside(p.node, r->node)) root = r;
    if (root == nullptr || !taken.insert(p.node).second) continue;
    const std::string node_name = p.node->mName.length ? p.node->mName.C_Str() : "(unnamed)";
    for (unsigned k = 0; k < p.node->mNumMeshes; ++k) {
      if (p.node->mMeshes[k] >= scene->mNumMeshes)
        throw Error(path, "node '" + node_name + "'", "names a mesh that does not exist");
      const aiMesh* mesh = scene->mMeshes[p.node->mMeshes[k]];
      const std::string mesh_name = mesh->mName.length ? mesh->mName.C_Str() : "(unnamed)";
      if ((mesh->mPrimitiveTypes & ~unsigned(aiPrimitiveType_TRIANGLE)) != 0)
        throw Error(
            path, "node '" + node_name + "'",
            "mesh '" + mesh_name + "' has point or line primitives; only triangles bound a volume");
      const std::size_t base = soup.points.size();
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        const aiVector3D& x = mesh->mVertices[v];
        const Eigen::Vector4d w = p.world * Eigen::Vector4d(x.x, x.y, x.z, 1.0);
        if (!w.allFinite())
          throw Error(path, "node '" + node_name + "'",
                      "mesh '" + mesh_name + "' vertex " + std::to_string(v) +
                          " is not finite after the node transforms");
        soup.points.push_back({w[0], w[1], w[2]});
      }
      for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
        const aiFace& face = mesh->mFaces[f];
        if (face.mNumIndices != 3)
          throw Error(path, "node '" + node_name + "'",
                      "mesh '" + mesh_name + "' face " + std::to_string(f) + " has " +
                          std::to_string(face.mNumIndices) + " corners, not 3");
        std::vector<std::size_t> tri(3);
        for (int c = 0; c < 3; ++c) {
          if (face.mIndices[c] >= mesh->mNumVertices)
            throw Error(path, "node '" + node_name + "'",
                        "mesh '" + mesh_name + "' face " + std::to_string(f) +
                            " names a vertex that does not exist");
          tri[std::size_t(c)] = base + face.mIndices[c];
        }
        soup.polygons.push_back(std::move(tri));
      }
    }
  }
  if (soup.polygons.empty())
    throw Error(path, nodes.empty() ? "" : "node '" + nodes.front() + "'",
                "the selected node(s) carry no triangle mesh");
  return soup;
}

}  // namespace fsm::build
