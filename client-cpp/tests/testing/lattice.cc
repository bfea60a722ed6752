#include "tests/testing/lattice.h"

#include <utility>

namespace actopo::client::testing {

Lattice::Lattice(int n) {
  auto id = [n](int i, int j, int k) { return int64_t(i) + n * (int64_t(j) + int64_t(n) * k); };
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i < n; ++i) {
        const double x = double(i) / (n - 1), y = double(j) / (n - 1), z = double(k) / (n - 1);
        points.insert(points.end(), {x, y, z});
        height.push_back(z + 0.1 * y + 0.01 * x);
      }
    }
  }
  constexpr std::array<std::array<int, 3>, 6> kAxes = {
      {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}}};
  for (int k = 0; k + 1 < n; ++k) {
    for (int j = 0; j + 1 < n; ++j) {
      for (int i = 0; i + 1 < n; ++i) {
        for (const auto& axes : kAxes) {
          int c[3] = {i, j, k};
          std::array<int64_t, 4> tet;
          tet[0] = id(c[0], c[1], c[2]);
          for (int step = 0; step < 3; ++step) {
            ++c[axes[step]];
            tet[step + 1] = id(c[0], c[1], c[2]);
          }
          if (Volume(tet) < 0) std::swap(tet[2], tet[3]);
          tetrahedra.insert(tetrahedra.end(), tet.begin(), tet.end());
        }
      }
    }
  }
  tetrahedra32.assign(tetrahedra.begin(), tetrahedra.end());
}

double Lattice::Volume(const std::array<int64_t, 4>& t) const {
  double d[3][3];
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) d[r][c] = points[3 * t[r + 1] + c] - points[3 * t[0] + c];
  }
  return d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1]) -
         d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0]) +
         d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0]);
}

}  // namespace actopo::client::testing
