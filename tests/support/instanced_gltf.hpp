// A small glTF file whose node hierarchy places one mesh several times, for the loader's and the CLI's tests
// of instances (LoadOptions::keep_instances, `lancer info`).
#pragma once

#include <filesystem>
#include <fstream>
#include <string>

namespace lancer::test {

// Writes placed.gltf (and its positions, mesh.bin) into `dir` and returns its path: three one-triangle
// meshes, mesh 0 placed by three nodes (translated; scaled and translated; the child, translated, of a node
// rotated a quarter turn about z and translated), mesh 1 by one, mesh 2 by two, the second with a zero
// scale (singular). Depth-first, the placements are mesh 0 by nodes 0, 1 and 4, mesh 1, mesh 2 twice.
inline std::filesystem::path write_instanced_gltf(const std::filesystem::path& dir) {
    const float positions[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0,
                               1, 1, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1};
    std::ofstream(dir / "mesh.bin", std::ios::binary)
        .write(reinterpret_cast<const char*>(positions), sizeof(positions));
    const std::string accessors = R"(
      {"bufferView": 0, "byteOffset": 0, "componentType": 5126, "count": 3, "type": "VEC3",
       "min": [0, 0, 0], "max": [1, 1, 0]},
      {"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3",
       "min": [0, 0, 0], "max": [1, 0, 1]},
      {"bufferView": 0, "byteOffset": 72, "componentType": 5126, "count": 3, "type": "VEC3",
       "min": [0, 0, 0], "max": [0, 1, 1]})";
    const std::filesystem::path file = dir / "placed.gltf";
    std::ofstream(file) << (R"({
  "asset": {"version": "2.0"},
  "scene": 0,
  "scenes": [{"nodes": [0, 1, 2, 3, 5, 6]}],
  "nodes": [
    {"mesh": 0, "translation": [10, 0, 0]},
    {"mesh": 0, "scale": [2, 2, 2], "translation": [0, 20, 0]},
    {"rotation": [0, 0, 0.7071067811865476, 0.7071067811865476], "translation": [0, 0, 5], "children": [4]},
    {"mesh": 1},
    {"mesh": 0, "translation": [1, 0, 0]},
    {"mesh": 2, "translation": [0, 0, 7]},
    {"mesh": 2, "scale": [0, 1, 1]}
  ],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]},
             {"primitives": [{"attributes": {"POSITION": 1}}]},
             {"primitives": [{"attributes": {"POSITION": 2}}]}],
  "buffers": [{"uri": "mesh.bin", "byteLength": 108}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 108}],
  "accessors": [)" + accessors +
                            R"(
  ]
})");
    return file;
}

}  // namespace lancer::test
