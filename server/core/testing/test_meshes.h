// Small meshes for core tests, built without VTK.
#ifndef ACTOPO_SERVER_CORE_TESTING_TEST_MESHES_H_
#define ACTOPO_SERVER_CORE_TESTING_TEST_MESHES_H_

#include <cstdint>

#include "server/core/mesh.h"

namespace actopo::testing {

// One tetrahedron, field "height".
Mesh SingleTetrahedron();

// An nx * ny * nz lattice, each cube split into 6 tetrahedra (Freudenthal), field "height" (a
// bumpy function with several extrema) and "z". With shuffle_seed != 0 vertex and tetrahedron ids
// are shuffled, so input order and block order differ.
Mesh Lattice(int nx, int ny, int nz, uint64_t shuffle_seed = 0);

// Two lattices far apart in one mesh: two components, each with its own boundary.
Mesh TwoComponents();

// Non-manifold on purpose: a triangle shared by three tetrahedra, two tetrahedra touching at a
// single vertex and two touching along a single edge.
Mesh NonManifold();

// A vertex with many neighbours: the centre (input vertex 0) of a bipyramid over a ring of
// `ring` vertices (then the apexes 1 and 2). Closed, the centre is inside; without the lower
// half, on the boundary. Field "distance" (from the centre, ties broken by id).
Mesh Bipyramid(int ring, bool closed);

// A block label per vertex for LabelBlocks: the vertex's x-slice (distinct x coordinates, in
// order) modulo `blocks`. On a lattice, neighbours along x then lie in different blocks, about
// V / blocks apart in vertex order: the far-in-id paths of the encodings that store differences.
std::vector<double> SliceLabels(const Mesh& mesh, int blocks);

}  // namespace actopo::testing

#endif  // ACTOPO_SERVER_CORE_TESTING_TEST_MESHES_H_
