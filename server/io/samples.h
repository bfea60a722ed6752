// Built-in deterministic sample meshes, addressed by name, for demos, tests and benchmarks
// without data files.
//
//   ASSIGN_OR_RETURN(actopo::Mesh mesh, actopo::io::MakeSample("jittered:64"));
//
// Names (N is the number of points per axis):
//   wavelet[:N]   ParaView's Wavelet source (vtkRTAnalyticSource, field "RTData") on N^3 points
//                 centred on 0 (wavelet:21 is ParaView's default extent -10..10), split by
//                 Tetrahedralize (vtkDataSetTriangleFilter) into 5 tetrahedra per voxel.
//   jittered[:N]  an irregular mesh of the unit cube built without VTK: an N^3 lattice with every
//                 point moved by a hashed offset of up to 0.1 spacing per axis (boundary points
//                 stay on their faces), 6 positively oriented tetrahedra per cube (Freudenthal
//                 split), fields "scalar" (smooth, several extrema) and "height" (z).
// The same name always gives the same mesh, bit for bit. A name may be written with the
// "sample:" prefix clients use to tell a sample from a file ("sample:wavelet:16").
#ifndef ACTOPO_SERVER_IO_SAMPLES_H_
#define ACTOPO_SERVER_IO_SAMPLES_H_

#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "server/core/mesh.h"
#include "server/io/mesh_header.h"

namespace actopo::io {

// InvalidArgument, naming the value and listing the samples, for an unknown name or a bad N.
absl::StatusOr<Mesh> MakeSample(std::string_view name);
// The size of MakeSample(name), without making it (errors as MakeSample's).
absl::StatusOr<MeshCounts> SampleCounts(std::string_view name);

// Whether `name` is a sample MakeSample makes ("wavelet:16", "sample:wavelet:16").
bool IsSampleName(std::string_view name);

// One line per sample, "name:N  description", for --help and server info.
std::vector<std::string> SampleNames();

}  // namespace actopo::io

#endif  // ACTOPO_SERVER_IO_SAMPLES_H_
