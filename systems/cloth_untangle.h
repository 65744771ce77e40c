#pragma once
// Untangling cloth that is already crossed: intersection contour minimisation (Volino and
// Magnenat-Thalmann 2006, "Resolving surface collisions through intersection contour minimization").
//
// Two triangles that cross meet along a segment; the segments of all the crossed pairs make up the
// intersection contour, a set of curves along which the surfaces pass through each other. A contour that
// shrinks to nothing leaves the surfaces apart, whichever way they crossed, so no history is needed: a
// cloth loaded crossed, one a pinned mass dragged through itself, and two sheets that pass through each
// other all come clean the same way. The gradient of the contour's length is taken here with respect to
// each triangle's and each edge's position as a whole (the change of each spread over its corners by
// their weights at the crossing point), as Volino and Magnenat-Thalmann do.
//
// A segment's end is where an edge E of one triangle meets the other triangle (unit normal n); moving the
// triangle by D moves that point by E (n . D) / (n . E), and moving the edge by D moves it by
// D - E (n . D) / (n . E). With g the length's gradient at the point (the segment's direction, away
// from its other end), the triangle's share of the gradient is n (g . E) / (n . E) and the edge's
// g - n (g . E) / (n . E). The ratio (g . E) / (n . E) grows without bound as the edge lies down in the
// triangle's plane; it is clamped (kMaxRatio), which keeps the direction and bounds the step.

#include "engine/math.h"
#include "systems/bvh.h"

#include <array>
#include <cstdint>
#include <vector>

namespace tumble {

/// The contour's length over the given crossed pairs of triangles at positions x, and its gradient with
/// respect to every vertex added into grad (sized like x). A pair whose triangles meet in other than one
/// segment (touching at a point, coplanar, no longer crossed) adds nothing.
double contourGradient(const std::vector<Vec3>& x, const std::vector<Triangle>& tris,
                       const std::vector<std::array<std::uint32_t, 2>>& pairs, std::vector<Vec3>& grad);

/// The edges of a triangle mesh as a graph over its vertices (each vertex's neighbours, in order).
struct VertexGraph {
    std::vector<std::uint32_t>
        start; ///< per vertex, where its neighbours begin in `next` (one past the end last)
    std::vector<std::uint32_t> next;
    void build(std::size_t vertices, const std::vector<Triangle>& tris);
};

/// Global intersection analysis (after Baraff, Witkin and Kass 2003, "Untangling cloth"): which parts of
/// the cloth are on the wrong side of another, and which way they go back through it.
///
/// Every edge that passes through a triangle it crosses (an edge of one triangle of a crossed pair through
/// the other) is cut; the vertices, joined by the edges that are not cut, fall into regions. A contour
/// that closes, or that runs from a boundary to a boundary, cuts a region off: the part of the cloth
/// beyond it lies on the other side of the surface it passes through. Of the two regions either side of
/// a cut edge, the smaller (a region holding a held mass counts as endless: it cannot move) is the one to
/// pass back through that edge's triangle, towards the triangle's far side from it. Two regions that would
/// pass through each other (each across a cut of the other's) are not both chosen: the smaller goes first.
/// A contour that cuts nothing off (a slit: it ends inside both surfaces) chooses nothing, nor does a
/// region whose cuts disagree on the way back (their directions summing to less than half their number);
/// contour minimisation handles them.
struct RegionChoice {
    std::vector<std::uint32_t> region; ///< per vertex: its region
    std::vector<Vec3> direction;       ///< per vertex: the unit direction its region moves in, or zero
    std::size_t chosen = 0;            ///< regions chosen to move
    // scratch
    std::vector<std::uint32_t> size, queue, order;
    std::vector<std::array<std::uint32_t, 2>> cuts; ///< cut edges (sorted vertex pairs), sorted
    struct Cut {
        std::uint32_t a, b, t; ///< the edge and the triangle it passes through
    };
    std::vector<Cut> cutList;
    std::vector<Vec3> sum;            ///< per region: the summed directions of its cuts
    std::vector<std::uint32_t> votes; ///< and their number
    std::vector<std::uint8_t> candidate, accepted;
    std::vector<std::array<std::uint32_t, 2>> across; ///< (region, region on the far side of one of its cuts)
};

/// Fills `out` for the crossed pairs at positions x. held: per vertex, 1 for a mass that cannot be moved.
void chooseRegions(const std::vector<Vec3>& x, const std::vector<Triangle>& tris, const VertexGraph& graph,
                   const std::vector<std::array<std::uint32_t, 2>>& pairs,
                   const std::vector<std::uint8_t>& held, RegionChoice& out);

} // namespace tumble
