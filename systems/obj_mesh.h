#pragma once
// Reading the meshes of `convex` and `mesh` rigid bodies from Wavefront OBJ files: `v x y z` and `f a b c`
// lines only (polygons are fanned into triangles; texture and normal indices after '/' are skipped; other
// lines ignored). Written here because none of the packages Tumble builds on reads OBJ, and the rocks and
// the mountainside need no more than this.

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
