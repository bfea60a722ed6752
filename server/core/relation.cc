#include "server/core/relation.h"

namespace actopo {
namespace {

struct RelationInfo {
  Relation relation;
  std::string_view code;
  std::string_view name;
};

constexpr std::array<RelationInfo, kNumRelations> kRelations = {{
    {Relation::kVV, "VV", "vertex_neighbors"},
    {Relation::kVE, "VE", "vertex_edges"},
    {Relation::kVF, "VF", "vertex_triangles"},
    {Relation::kVT, "VT", "vertex_star"},
    {Relation::kEV, "EV", "edge_vertices"},
    {Relation::kEF, "EF", "edge_triangles"},
    {Relation::kET, "ET", "edge_star"},
    {Relation::kFV, "FV", "triangle_vertices"},
    {Relation::kFE, "FE", "triangle_edges"},
    {Relation::kFT, "FT", "triangle_star"},
    {Relation::kTV, "TV", "tetrahedron_vertices"},
    {Relation::kTE, "TE", "tetrahedron_edges"},
    {Relation::kTF, "TF", "tetrahedron_triangles"},
    {Relation::kTT, "TT", "tetrahedron_neighbors"},
    {Relation::kVL, "VL", "vertex_link"},
    {Relation::kEL, "EL", "edge_link"},
    {Relation::kFL, "FL", "triangle_link"},
    {Relation::kVB, "VB", "vertex_on_boundary"},
    {Relation::kEB, "EB", "edge_on_boundary"},
    {Relation::kFB, "FB", "triangle_on_boundary"},
    {Relation::kEE, "EE", "edge_neighbors"},
    {Relation::kFF, "FF", "triangle_neighbors"},
}};

constexpr std::array<Relation, kNumRelations> kAll = [] {
  std::array<Relation, kNumRelations> all{};
  for (int i = 0; i < kNumRelations; ++i) all[i] = kRelations[i].relation;
  return all;
}();

}  // namespace

std::string_view RelationName(Relation r) { return kRelations[Index(r)].name; }
std::string_view RelationCode(Relation r) { return kRelations[Index(r)].code; }

std::optional<Relation> ParseRelation(std::string_view name) {
  for (const RelationInfo& info : kRelations) {
    if (info.name == name || info.code == name) return info.relation;
  }
  return std::nullopt;
}

std::span<const Relation> AllRelations() { return kAll; }

}  // namespace actopo
