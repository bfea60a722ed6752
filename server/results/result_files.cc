#include "server/results/result_files.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numeric>

#include "absl/strings/str_cat.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"
#include "server/io/vtk_writer.h"

namespace actopo {
namespace {

using io::NamedArray;
using io::PolyData;

// Barycentre of a cell given by internal ids into xyz[0..2]: its vertices' points summed in
// ascending input id. No allocation: a Morse-Smale result places millions of separatrix points.
void Barycentre(const ResultContext& c, int dim, SimplexId id, double* xyz) {
  SimplexId vertices[4];
  CellTokens(c.topology, dim, id, vertices);
  double p[3] = {0, 0, 0};
  for (int i = 0; i <= dim; ++i) {
    for (int k = 0; k < 3; ++k) p[k] += c.mesh.points[3 * size_t(vertices[i]) + k];
  }
  for (int k = 0; k < 3; ++k) xyz[k] = p[k] / double(dim + 1);
}

void AppendBarycentre(const ResultContext& c, int dim, SimplexId id, std::vector<double>& points) {
  double xyz[3];
  Barycentre(c, dim, id, xyz);
  points.insert(points.end(), xyz, xyz + 3);
}

// The cell's highest vertex in the vertex order (TTK's "greater vertex"), as an input id.
SimplexId HighestVertex(const ResultContext& c, int dim, SimplexId id) {
  SimplexId vertices[4];
  CellTokens(c.topology, dim, id, vertices);
  return *std::max_element(vertices, vertices + dim + 1, [&](SimplexId a, SimplexId b) {
    if (!c.order.empty()) return c.order[a] < c.order[b];
    return c.scalars[a] < c.scalars[b] || (c.scalars[a] == c.scalars[b] && a < b);
  });
}

// TTK reports cells by id: vertices and tetrahedra in input ids; edges and triangles in this
// service's numbering (sorted vertex tuples identify them unambiguously).
SimplexId ReportedId(const ResultContext& c, int dim, SimplexId id) {
  if (dim == 0) return c.topology.vertex_input_id(id);
  if (dim == 3) return c.topology.tetrahedron_input_id(id);
  return id;
}

// Critical cells as points with CellDimension, CellId, ttkVertexScalarField, the scalar and
// IsOnBoundary (of the highest vertex, as TTK).
PolyData CriticalCellPoints(const ResultContext& c, const std::vector<Cell>& cells,
                            std::vector<int32_t>* manifold_size) {
  PolyData out;
  std::vector<int8_t> dims, boundary;
  std::vector<int32_t> ids, highest;
  std::vector<double> scalar;
  std::vector<SimplexId> highest_internal;
  for (const Cell& cell : cells) {
    highest.push_back(HighestVertex(c, cell.dim, cell.id));
    highest_internal.push_back(c.topology.vertex_internal_id(highest.back()));
  }
  c.vertex_on_boundary->Prepare(highest_internal, DefaultThreads());
  for (size_t i = 0; i < cells.size(); ++i) {
    const Cell& cell = cells[i];
    AppendBarycentre(c, cell.dim, cell.id, out.points);
    dims.push_back(cell.dim);
    ids.push_back(ReportedId(c, cell.dim, cell.id));
    scalar.push_back(c.scalars[highest[i]]);
    boundary.push_back((*c.vertex_on_boundary)(highest_internal[i]));
  }
  out.point_arrays = {{"CellDimension", std::move(dims)},
                      {"CellId", std::move(ids)},
                      {"ttkVertexScalarField", std::move(highest)},
                      {c.scalar_name, std::move(scalar)},
                      {"IsOnBoundary", std::move(boundary)}};
  if (manifold_size != nullptr) out.point_arrays.push_back({"ManifoldSize", *manifold_size});
  return out;
}

std::vector<Cell> CriticalCells(const DiscreteGradientResult& g) {
  std::vector<Cell> cells;
  for (int d = 0; d < 4; ++d) {
    for (SimplexId id : g.critical[d]) cells.push_back({int8_t(d), id});
  }
  return cells;
}

PolyData CriticalPointsPolyData(const ResultContext& c, const CriticalPointsResult& r) {
  PolyData out;
  std::vector<int8_t> type, boundary;
  std::vector<int32_t> id;
  std::vector<double> scalar;
  for (const CriticalPoint& p : r.points) {
    for (int k = 0; k < 3; ++k) out.points.push_back(c.mesh.points[3 * size_t(p.vertex) + k]);
    type.push_back(int8_t(p.type));
    boundary.push_back(p.on_boundary);
    id.push_back(p.vertex);
    scalar.push_back(c.scalars[p.vertex]);
  }
  out.point_arrays = {{"ttkVertexScalarField", std::move(id)},
                      {"CriticalType", std::move(type)},
                      {"IsOnBoundary", std::move(boundary)},
                      {c.scalar_name, std::move(scalar)}};
  return out;
}

void AddMorseSmaleOutputs(const ResultContext& c, const MorseSmaleResult& r, ResultOutputs& out) {
  // Critical points with the size of their manifold (minima: descending, maxima: ascending).
  const std::vector<Cell> cells = CriticalCells(r.gradient);
  std::vector<int32_t> manifold_size(cells.size(), 0);
  std::vector<std::pair<SimplexId, size_t>> minima, maxima;  // (input id, index in cells)
  for (size_t i = 0; i < cells.size(); ++i) {
    if (cells[i].dim == 0) minima.push_back({ReportedId(c, 0, cells[i].id), i});
    if (cells[i].dim == 3) maxima.push_back({ReportedId(c, 3, cells[i].id), i});
  }
  std::sort(minima.begin(), minima.end());
  std::sort(maxima.begin(), maxima.end());
  for (size_t k = 0; k < minima.size(); ++k) manifold_size[minima[k].second] = r.minimum_sizes[k];
  for (size_t k = 0; k < maxima.size(); ++k) manifold_size[maxima[k].second] = r.maximum_sizes[k];
  out.poly_data.push_back({"critical_points", CriticalCellPoints(c, cells, &manifold_size)});

  // One polyline per separatrix through its cells' barycentres, in order: the points are sized
  // up front (grown by doubling, the points would be held up to three times while the last
  // growth copied them) and placed by every core, each separatrix at its line's offset.
  const size_t num_lines = r.separatrices.size();
  PolyData seps;
  seps.line_offsets.resize(num_lines + 1);
  seps.line_offsets[0] = 0;
  for (size_t i = 0; i < num_lines; ++i) {
    seps.line_offsets[i + 1] = seps.line_offsets[i] + int32_t(r.separatrices[i].path.size());
  }
  const size_t num_points = size_t(seps.line_offsets[num_lines]);
  seps.line_connectivity.resize(num_points);
  std::iota(seps.line_connectivity.begin(), seps.line_connectivity.end(), 0);
  seps.points.resize(3 * num_points);
  ParallelFor(int64_t(num_lines), DefaultThreads(), [&](int64_t i, int) {
    double* xyz = &seps.points[3 * size_t(seps.line_offsets[i])];
    const Separatrix& s = r.separatrices[i];
    for (size_t k = 0; k < s.path.size(); ++k) {
      Barycentre(c, s.dimension(k), s.path[k], xyz);
      xyz += 3;
    }
  });
  std::vector<int32_t> source, destination, separatrix_id;
  std::vector<int8_t> type;
  for (size_t i = 0; i < num_lines; ++i) {
    const Separatrix& s = r.separatrices[i];
    source.push_back(ReportedId(c, s.source.dim, s.source.id));
    destination.push_back(ReportedId(c, s.destination.dim, s.destination.id));
    separatrix_id.push_back(int32_t(i));
    type.push_back(int8_t(s.type));
  }
  seps.cell_arrays = {{"SourceId", std::move(source)},
                      {"DestinationId", std::move(destination)},
                      {"SeparatrixId", std::move(separatrix_id)},
                      {"SeparatrixType", std::move(type)}};
  if (r.separatrices.empty()) seps.line_offsets.clear();
  out.poly_data.push_back({"separatrices", std::move(seps)});

  out.segmentation = {
      {"DescendingManifold", std::vector<int32_t>(r.descending.begin(), r.descending.end())},
      {"AscendingManifold", std::vector<int32_t>(r.ascending.begin(), r.ascending.end())},
      {"MorseSmaleManifold", std::vector<int32_t>(r.morse_smale.begin(), r.morse_smale.end())}};
}

// TTK's CriticalType of a pair's birth and death vertices.
int32_t BirthType(const PersistencePair& p) { return p.type; }
int32_t DeathType(const PersistencePair& p) { return p.finite() && p.type < 2 ? p.type + 1 : 3; }

// TTK's diagram: two points per pair, (birth, birth, 0) and (birth, death, 0), or the two
// vertices' positions when embedded in the domain; a line per pair; the diagonal last (not when
// embedded).
PolyData DiagramPolyData(const ResultContext& c, const PersistenceDiagramResult& r) {
  PolyData out;
  std::vector<int32_t> vertex, critical_type, pair_id, pair_type;
  std::vector<float> coordinates;
  std::vector<double> persistence, birth;
  std::vector<int8_t> finite;
  out.line_offsets.push_back(0);
  const auto add_point = [&](SimplexId v, int32_t type, double x, double y) {
    const double* p = &c.mesh.points[3 * size_t(v)];
    if (r.embed_in_domain) {
      out.points.insert(out.points.end(), p, p + 3);
    } else {
      out.points.insert(out.points.end(), {x, y, 0.0});
    }
    out.line_connectivity.push_back(int32_t(vertex.size()));
    vertex.push_back(v);
    critical_type.push_back(type);
    coordinates.insert(coordinates.end(), {float(p[0]), float(p[1]), float(p[2])});
  };
  for (size_t i = 0; i < r.pairs.size(); ++i) {
    const PersistencePair& p = r.pairs[i];
    add_point(p.birth, BirthType(p), p.birth_value, p.birth_value);
    add_point(p.death, DeathType(p), p.birth_value, p.death_value);
    out.line_offsets.push_back(int32_t(out.line_connectivity.size()));
    pair_id.push_back(int32_t(i));
    pair_type.push_back(p.type);
    persistence.push_back(p.Persistence());
    birth.push_back(p.birth_value);
    finite.push_back(p.finite());
  }
  if (!r.pairs.empty() && !r.embed_in_domain) {
    out.line_connectivity.insert(out.line_connectivity.end(),
                                 {0, int32_t(2 * (r.pairs.size() - 1))});
    out.line_offsets.push_back(int32_t(out.line_connectivity.size()));
    pair_id.push_back(-1);
    pair_type.push_back(-1);
    persistence.push_back(2 * persistence[0]);
    birth.push_back(0);
    finite.push_back(0);
  }
  if (r.pairs.empty()) out.line_offsets.clear();
  out.point_arrays = {{"ttkVertexScalarField", std::move(vertex)},
                      {"CriticalType", std::move(critical_type)},
                      {"Coordinates", std::move(coordinates), 3}};
  out.cell_arrays = {{"PairIdentifier", std::move(pair_id)},
                     {"PairType", std::move(pair_type)},
                     {"Persistence", std::move(persistence)},
                     {"Birth", std::move(birth)},
                     {"IsFinite", std::move(finite)}};
  return out;
}

// TTK's persistence curves, one after another: per type 0, 1, 2 and then all pairs (-1).
std::vector<io::NamedArray> CurveTable(const PersistenceDiagramResult& r) {
  std::vector<double> persistence;
  std::vector<int32_t> pairs;
  std::vector<int8_t> type;
  for (int t : {0, 1, 2, -1}) {
    const PersistenceCurve curve = ComputePersistenceCurve(r, t);
    persistence.insert(persistence.end(), curve.persistence.begin(), curve.persistence.end());
    pairs.insert(pairs.end(), curve.pairs.begin(), curve.pairs.end());
    type.insert(type.end(), curve.pairs.size(), int8_t(t));
  }
  return {{"PairType", std::move(type)},
          {"Persistence", std::move(persistence)},
          {"NumberOfPairs", std::move(pairs)}};
}

absl::Status WriteCsv(const std::string& path, std::span<const io::NamedArray> columns) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": cannot write: ", std::strerror(errno)));
  }
  for (size_t k = 0; k < columns.size(); ++k) {
    std::fprintf(f, "%s%s", k ? "," : "", columns[k].name.c_str());
  }
  std::fprintf(f, "\n");
  const size_t rows = columns.empty() ? 0 : columns[0].size();
  for (size_t i = 0; i < rows; ++i) {
    for (size_t k = 0; k < columns.size(); ++k) {
      std::visit([&](const auto& v) { std::fprintf(f, "%s%.17g", k ? "," : "", double(v[i])); },
                 columns[k].values);
    }
    std::fprintf(f, "\n");
  }
  if (std::fclose(f) != 0) {
    return absl::InternalError(absl::StrCat(path, ": cannot write: ", std::strerror(errno)));
  }
  return absl::OkStatus();
}

// TTK's TopologicalSimplification outputs: the field under its own name and its order.
std::vector<io::NamedArray> SimplifiedArrays(const ResultContext& c,
                                             const SimplificationResult& s) {
  return {{c.scalar_name, s.scalars},
          {c.scalar_name + "_Order", std::vector<int32_t>(s.order.begin(), s.order.end())}};
}

// TTK's span of an arc (Geometry::distance over float coordinates): the distance between its two
// nodes' vertices, computed in float. TTK is built with -march=native, so GCC fuses each step
// of its sum into an FMA on any machine that has one: fmaf here gives its values bit for bit.
float ArcSpan(const ResultContext& c, const TreeResult& r, const TreeArc& a) {
  const double* p = &c.mesh.points[3 * size_t(r.nodes[a.down_node].vertex)];
  const double* q = &c.mesh.points[3 * size_t(r.nodes[a.up_node].vertex)];
  float sum = 0;
  for (int k = 0; k < 3; ++k) {
    const float d = float(p[k]) - float(q[k]);
    sum = std::fma(d, d, sum);
  }
  return std::sqrt(sum);
}

// TTK's three tree outputs: nodes and arcs (their points at the nodes' vertices) and the
// segmentation (per vertex, its arc's values).
void AddTreeOutputs(const ResultContext& c, const TreeResult& r, ResultOutputs& out) {
  std::vector<float> span(r.arcs.size());
  for (size_t i = 0; i < r.arcs.size(); ++i) span[i] = ArcSpan(c, r, r.arcs[i]);
  const auto scalar = [&](SimplexId v) { return float(c.scalars[v]); };

  PolyData nodes;
  std::vector<int32_t> node_id, vertex_id, type, size, node_span, node_component;
  std::vector<float> node_scalar;
  for (size_t n = 0; n < r.nodes.size(); ++n) {
    const TreeNode& node = r.nodes[n];
    const double* p = &c.mesh.points[3 * size_t(node.vertex)];
    nodes.points.insert(nodes.points.end(), p, p + 3);
    node_id.push_back(int32_t(n));
    node_scalar.push_back(scalar(node.vertex));
    vertex_id.push_back(node.vertex);
    type.push_back(int32_t(node.type));
    size.push_back(r.arcs[node.region_arc].region_size);
    node_span.push_back(int32_t(span[node.region_arc]));  // TTK truncates toward zero
    node_component.push_back(r.ComponentOf(int32_t(n)));
  }
  // ComponentId is ours, not TTK's: the component whose first NodeId upNodeId and downNodeId
  // are relative to, so that clients need not work it out.
  nodes.point_arrays = {{"NodeId", std::move(node_id)},
                        {"Scalar", std::move(node_scalar)},
                        {"VertexId", std::move(vertex_id)},
                        {"CriticalType", std::move(type)},
                        {"RegionSize", std::move(size)},
                        {"RegionSpan", std::move(node_span)},
                        {"ComponentId", std::move(node_component)}};
  out.poly_data.push_back({"tree_nodes", std::move(nodes)});

  // One line per arc from its lower-valued node to the other; a point per node, at first use.
  PolyData arcs;
  std::vector<int32_t> point_of(r.nodes.size(), -1);
  std::vector<float> point_scalar;
  const auto point = [&](int32_t node) {
    if (point_of[node] < 0) {
      point_of[node] = int32_t(point_scalar.size());
      const double* p = &c.mesh.points[3 * size_t(r.nodes[node].vertex)];
      arcs.points.insert(arcs.points.end(), p, p + 3);
      point_scalar.push_back(scalar(r.nodes[node].vertex));
    }
    return point_of[node];
  };
  std::vector<int32_t> segmentation_id, up, down, arc_size, arc_component;
  std::vector<double> arc_span;
  arcs.line_offsets.push_back(0);
  for (size_t i = 0; i < r.arcs.size(); ++i) {
    const TreeArc& a = r.arcs[i];
    const bool down_is_lower = r.type != TreeType::kSplit;
    const int32_t lower = down_is_lower ? a.down_node : a.up_node;
    const int32_t upper = down_is_lower ? a.up_node : a.down_node;
    const int32_t from = point(lower);
    arcs.line_connectivity.insert(arcs.line_connectivity.end(), {from, point(upper)});
    arcs.line_offsets.push_back(int32_t(arcs.line_connectivity.size()));
    segmentation_id.push_back(a.segmentation_id);
    up.push_back(r.LocalNodeId(a.up_node));
    down.push_back(r.LocalNodeId(a.down_node));
    arc_component.push_back(r.ComponentOf(a.down_node));
    arc_size.push_back(a.region_size);
    arc_span.push_back(span[i]);
  }
  if (r.arcs.empty()) arcs.line_offsets.clear();
  const size_t num_points = point_scalar.size();
  arcs.point_arrays = {{"Scalar", std::move(point_scalar)},
                       {"ttkMaskScalarField", std::vector<int8_t>(num_points, 0)}};
  arcs.cell_arrays = {{"SegmentationId", std::move(segmentation_id)},
                      {"upNodeId", std::move(up)},
                      {"downNodeId", std::move(down)},
                      {"RegionSize", std::move(arc_size)},
                      {"RegionSpan", std::move(arc_span)},
                      {"ComponentId", std::move(arc_component)}};
  out.poly_data.push_back({"tree_arcs", std::move(arcs)});

  const size_t n = r.vertex_arc.size();
  std::vector<int32_t> vertex_segmentation(n), vertex_size(n);
  std::vector<double> vertex_span(n);
  std::vector<int8_t> region_type(n);
  ParallelForRanges(int64_t(n), 1 << 16, DefaultThreads(), [&](int64_t begin, int64_t end) {
    for (int64_t v = begin; v < end; ++v) {
      const int32_t a = r.vertex_arc[v];
      vertex_segmentation[v] = r.arcs[a].segmentation_id;
      vertex_size[v] = r.arcs[a].region_size;
      vertex_span[v] = span[a];
      region_type[v] = r.arcs[a].region_type;
    }
  });
  out.segmentation = {{"SegmentationId", std::move(vertex_segmentation)},
                      {"RegionSize", std::move(vertex_size)},
                      {"RegionSpan", std::move(vertex_span)},
                      {"RegionType", std::move(region_type)}};
}

}  // namespace

std::vector<SimplexId> CellInputVertices(const Topology& topology, int d, SimplexId c) {
  std::vector<SimplexId> v(size_t(d) + 1);
  CellTokens(topology, d, c, v.data());
  return v;
}

ResultOutputs BuildOutputs(const ResultContext& c, const AlgorithmResult& result) {
  ResultOutputs out;
  if (const auto* r = std::get_if<CriticalPointsResult>(&result)) {
    out.poly_data.push_back({"critical_points", CriticalPointsPolyData(c, *r)});
  } else if (const auto* g = std::get_if<DiscreteGradientResult>(&result)) {
    out.poly_data.push_back({"critical_cells", CriticalCellPoints(c, CriticalCells(*g), nullptr)});
  } else if (const auto* m = std::get_if<MorseSmaleResult>(&result)) {
    AddMorseSmaleOutputs(c, *m, out);
  } else if (const auto* d = std::get_if<PersistenceDiagramResult>(&result)) {
    out.poly_data.push_back({"diagram", DiagramPolyData(c, *d)});
    out.tables.push_back({"persistence_curve", CurveTable(*d)});
  } else if (const auto* s = std::get_if<SimplificationResult>(&result)) {
    out.simplified = SimplifiedArrays(c, *s);
  } else if (const auto* t = std::get_if<TreeResult>(&result)) {
    AddTreeOutputs(c, *t, out);
  } else if (const auto* st = std::get_if<SimplifiedTreeResult>(&result)) {
    ResultContext simplified = c;
    simplified.scalars = st->simplification.scalars;
    simplified.order = st->simplification.order;
    AddTreeOutputs(simplified, st->tree, out);
    out.simplified = SimplifiedArrays(c, st->simplification);
  } else if (const auto* sm = std::get_if<SimplifiedMorseSmaleResult>(&result)) {
    // The complex is of the simplified field: its values and its order, as TTK's chain reports.
    ResultContext simplified = c;
    simplified.scalars = sm->simplification.scalars;
    simplified.order = sm->simplification.order;
    AddMorseSmaleOutputs(simplified, sm->morse_smale, out);
    out.simplified = SimplifiedArrays(c, sm->simplification);
  }
  return out;
}

absl::StatusOr<std::vector<std::string>> WriteResultFiles(const std::string& prefix,
                                                          const ResultContext& c,
                                                          const AlgorithmResult& result) {
  const ResultOutputs outputs = BuildOutputs(c, result);
  std::vector<std::string> written;
  for (const auto& [group, poly_data] : outputs.poly_data) {
    // TTK's diagrams are unstructured grids.
    const std::string path = prefix + "_" + group + (group == "diagram" ? ".vtu" : ".vtp");
    RETURN_IF_ERROR(io::WritePolyData(path, poly_data));
    written.push_back(path);
  }
  for (const auto& [name, columns] : outputs.tables) {
    const std::string path = prefix + "_" + name + ".csv";
    RETURN_IF_ERROR(WriteCsv(path, columns));
    written.push_back(path);
  }
  if (!outputs.simplified.empty()) {
    // The mesh with the simplified field in place of the original one, and its order.
    Mesh mesh = c.mesh;
    for (PointField& field : mesh.point_fields) {
      if (field.name == c.scalar_name) {
        field.values = std::get<std::vector<double>>(outputs.simplified[0].values);
        field.source_bytes = 8;  // streamed as float64, and written so by the clients too
      }
    }
    const std::string path = prefix + "_simplified.vtu";
    RETURN_IF_ERROR(io::WriteUnstructuredGrid(
        path, mesh, std::span<const io::NamedArray>(outputs.simplified).subspan(1)));
    written.push_back(path);
  }
  if (!outputs.segmentation.empty()) {
    const std::string path = prefix + "_segmentation.vtu";
    RETURN_IF_ERROR(io::WriteUnstructuredGrid(path, c.mesh, outputs.segmentation));
    written.push_back(path);
  }
  return written;
}

}  // namespace actopo
