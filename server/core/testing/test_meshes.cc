#include "server/core/testing/test_meshes.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

namespace actopo::testing {

Mesh SingleTetrahedron() {
  Mesh m;
  m.points = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.tetrahedra = {0, 1, 2, 3};
  m.point_fields.push_back({"height", {0.0, 0.5, 0.25, 1.0}});
  return m;
}

Mesh Lattice(int nx, int ny, int nz, uint64_t shuffle_seed) {
  Mesh m;
  auto id = [&](int i, int j, int k) { return SimplexId((k * ny + j) * nx + i); };
  PointField height{"height", {}}, zfield{"z", {}};
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const double x = i, y = j, z = k;
        m.points.insert(m.points.end(), {x, y, z});
        height.values.push_back(std::sin(0.9 * x) * std::cos(0.7 * y) + 0.3 * std::sin(1.3 * z) +
                                0.01 * x);
        zfield.values.push_back(z);
      }
  // Freudenthal split: the 6 monotone paths from corner 000 to corner 111.
  constexpr int kPaths[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k + 1 < nz; ++k)
    for (int j = 0; j + 1 < ny; ++j)
      for (int i = 0; i + 1 < nx; ++i)
        for (const auto& path : kPaths) {
          int c[3] = {i, j, k};
          m.tetrahedra.push_back(id(c[0], c[1], c[2]));
          for (int axis : path) {
            ++c[axis];
            m.tetrahedra.push_back(id(c[0], c[1], c[2]));
          }
        }
  m.point_fields = {std::move(height), std::move(zfield)};
  if (shuffle_seed == 0) return m;

  std::mt19937_64 rng(shuffle_seed);
  const SimplexId nv = m.num_vertices(), nt = m.num_tetrahedra();
  std::vector<SimplexId> new_id(nv);
  std::iota(new_id.begin(), new_id.end(), 0);
  std::shuffle(new_id.begin(), new_id.end(), rng);
  Mesh out;
  out.points.resize(m.points.size());
  for (SimplexId v = 0; v < nv; ++v)
    std::copy_n(&m.points[3 * size_t(v)], 3, &out.points[3 * size_t(new_id[v])]);
  for (const PointField& f : m.point_fields) {
    PointField g{f.name, std::vector<double>(nv)};
    for (SimplexId v = 0; v < nv; ++v) g.values[new_id[v]] = f.values[v];
    out.point_fields.push_back(std::move(g));
  }
  std::vector<SimplexId> tet_order(nt);
  std::iota(tet_order.begin(), tet_order.end(), 0);
  std::shuffle(tet_order.begin(), tet_order.end(), rng);
  for (SimplexId t : tet_order)
    for (int k = 0; k < 4; ++k) out.tetrahedra.push_back(new_id[m.tetrahedra[4 * size_t(t) + k]]);
  return out;
}

Mesh TwoComponents() {
  Mesh a = Lattice(4, 3, 3, 7);
  const Mesh b = Lattice(3, 5, 2, 11);
  const SimplexId shift = a.num_vertices();
  for (size_t i = 0; i < b.points.size(); ++i)
    a.points.push_back(b.points[i] + (i % 3 == 0 ? 50 : 0));
  for (SimplexId v : b.tetrahedra) a.tetrahedra.push_back(v + shift);
  for (size_t f = 0; f < a.point_fields.size(); ++f) {
    auto& values = a.point_fields[f].values;
    values.insert(values.end(), b.point_fields[f].values.begin(), b.point_fields[f].values.end());
  }
  return a;
}

Mesh NonManifold() {
  Mesh m;
  m.points = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 1, 1, -1,  // 0-5
              0, 0, 2, 1, 0, 2, 0, 1, 2, 3, 3, 3, 4, 3, 3,  3, 4, 3,   // 6-11
              3, 3, 4, 5, 5, 5};                                       // 12-13
  m.tetrahedra = {0, 1,  2,  3,  0,  1,  2,  4, 0, 1, 2, 5,  // triangle (0,1,2) in three tets
                  3, 6,  7,  8,                              // touches the first at vertex 3
                  9, 10, 11, 12, 10, 11, 13, 8};             // last two share only edge (10,11)
  std::vector<double> h;
  for (SimplexId v = 0; v < m.num_vertices(); ++v) h.push_back(0.1 * v + m.points[3 * v + 2]);
  m.point_fields.push_back({"height", h});
  return m;
}

Mesh Bipyramid(int ring, bool closed) {
  Mesh m;
  m.points = {0, 0, 0, 0, 0, 1, 0, 0, -1};  // centre, top, bottom
  for (int i = 0; i < ring; ++i) {
    const double a = 6.283185307179586 * i / ring;
    m.points.insert(m.points.end(), {std::cos(a), std::sin(a), 0});
  }
  for (int i = 0; i < ring; ++i) {
    const SimplexId r0 = 3 + i, r1 = 3 + (i + 1) % ring;
    m.tetrahedra.insert(m.tetrahedra.end(), {0, r0, r1, 1});
    if (closed) m.tetrahedra.insert(m.tetrahedra.end(), {0, r0, r1, 2});
  }
  std::vector<double> distance;
  for (size_t i = 0; i < m.points.size(); i += 3) {
    distance.push_back(std::hypot(m.points[i], m.points[i + 1], m.points[i + 2]) +
                       1e-3 * double(i));
  }
  m.point_fields.push_back({"distance", std::move(distance)});
  return m;
}

std::vector<double> SliceLabels(const Mesh& mesh, int blocks) {
  std::vector<double> slices;
  for (size_t i = 0; i < mesh.points.size(); i += 3) slices.push_back(mesh.points[i]);
  std::sort(slices.begin(), slices.end());
  slices.erase(std::unique(slices.begin(), slices.end()), slices.end());
  std::vector<double> labels;
  for (size_t i = 0; i < mesh.points.size(); i += 3) {
    const auto slice = std::lower_bound(slices.begin(), slices.end(), mesh.points[i]);
    labels.push_back(double((slice - slices.begin()) % blocks));
  }
  return labels;
}

}  // namespace actopo::testing
