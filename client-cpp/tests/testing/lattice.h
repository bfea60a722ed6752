// A tetrahedral mesh made by the tests themselves, to upload: the unit cube as a lattice.
#ifndef ACTOPO_CLIENT_TESTS_TESTING_LATTICE_H_
#define ACTOPO_CLIENT_TESTS_TESTING_LATTICE_H_

#include <array>
#include <cstdint>
#include <vector>

namespace actopo::client::testing {

// An n^3 lattice of the unit cube, each cell split into 6 positively oriented tetrahedra around
// its main diagonal, with a tie-free linear field.
struct Lattice {
  explicit Lattice(int n);

  double Volume(const std::array<int64_t, 4>& t) const;
  int64_t vertices() const { return int64_t(points.size() / 3); }
  int64_t cells() const { return int64_t(tetrahedra.size() / 4); }

  std::vector<double> points, height;
  std::vector<int64_t> tetrahedra;
  std::vector<int32_t> tetrahedra32;
};

}  // namespace actopo::client::testing

#endif  // ACTOPO_CLIENT_TESTS_TESTING_LATTICE_H_
