#pragma once
// Reading the meshes of `convex` and `mesh` rigid bodies from Wavefront OBJ files: `v x y z` and `f a b c`
// lines only (polygons are fanned into triangles; texture and normal indices after '/' are skipped; other
// lines ignored). Our own, not Debian's tinyobjloader (2.0.0rc10), which was tried in its place (issue 24)
// and kept out: it reads a bad or missing number as 0 without a word (`v 1 2`, `v nan 0 0`), returns face
// indices out of range or below the first vertex, keeps no line per face for the messages, caps nothing
// while it parses, and its number parser overflows an int on `v 1e2147483649 0 0` (UBSan, in the first
// second of fuzzing); every check below would have stayed ours, around a second parser.

#include "components/rigid_body.h"

#include <memory>
#include <string>

namespace tumble {

/// Reads an OBJ file (a regular file of at most 256 MiB). Throws std::runtime_error naming file:line and
/// the problem.
std::shared_ptr<const ShapeMesh> readObjMesh(const std::string& file, const std::string& displayName);

/// The same, from the file's text: `displayName` is what messages call it.
std::shared_ptr<const ShapeMesh> parseObjMesh(const std::string& text, const std::string& displayName);

/// A convex body's mesh from a file's: checked to be a closed convex hull wound outward (else
/// std::runtime_error naming the file and the face's line), moved so that its centre of mass (uniform
/// density) is at the origin, with `centre` saying where that was in the file's frame.
std::shared_ptr<const ShapeMesh> convexHullMesh(const ShapeMesh& file);

/// Where a mesh named in a scenario is: an absolute path as it is; otherwise next to the scenario file,
/// else under the project's root (the folder that holds assets/). Empty when neither exists.
std::string findMeshFile(const std::string& name, const std::string& scenarioFile);

} // namespace tumble
