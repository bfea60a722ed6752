// ParaView's collection files (.pvd): a time series as one file per step, each with the same
// points and cells (SEMANTICS.md "Fields, series and ensembles on one mesh"). ReadMesh reads a
// .pvd as one mesh whose point fields are every step's, renamed "<field>_<step>" with the step's
// index zero-padded to the width of the last one (isabel_series.pvd's four steps of
// velocityMag: velocityMag_0 ... velocityMag_3; with 12 steps velocityMag_00 ... velocityMag_11),
// so that names sort in time order; each keeps its step's time value (PointField::time).
//
//   ASSIGN_OR_RETURN(std::vector<CollectionStep> steps, ReadCollection("series.pvd"));
#ifndef ACTOPO_SERVER_IO_COLLECTION_H_
#define ACTOPO_SERVER_IO_COLLECTION_H_

#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/core/progress.h"

namespace actopo::io {

struct CollectionStep {
  std::string path;  // the step's file, resolved against the .pvd's folder
  double time = 0;   // its "timestep" attribute (the step's index when it has none)
};

// The steps a .pvd lists, in its order. Errors name the file and what is wrong with it.
absl::StatusOr<std::vector<CollectionStep>> ReadCollection(const std::string& path);

// The name of `field` at step `step` of `steps`: "<field>_<step>", zero-padded.
std::string SeriesFieldName(const std::string& field, size_t step, size_t steps);

// Adds `next` (step `index` of `count`, read from `file`) to `series` (step 0, read from
// `first`): its point fields renamed, after checking it has the same points and tetrahedra in
// the same order; otherwise INVALID_ARGUMENT naming `file` and the first difference.
absl::Status AppendSeriesStep(Mesh& series, const std::string& first, Mesh next,
                              const std::string& file, size_t index, size_t count, double time);

// Reads a file of a series: io::ReadMesh, or the server's isolated reader. `fields_before` is
// how many point fields the steps before it brought (the server's budget counts them all).
using StepReader = std::function<absl::StatusOr<Mesh>(const std::string& file, int fields_before,
                                                      const Progress& progress)>;

// Every step read with `read` and joined into one mesh (AppendSeriesStep), each step reporting
// its share of phase "read". Errors start with `series` (the .pvd, or how the caller names a
// list of files) and the step's index.
absl::StatusOr<Mesh> ReadSteps(const std::vector<CollectionStep>& steps, const StepReader& read,
                               const std::string& series, const Progress& progress);

}  // namespace actopo::io

#endif  // ACTOPO_SERVER_IO_COLLECTION_H_
