#include "server/core/testing/oracle.h"

#include <algorithm>
#include <map>
#include <set>

namespace actopo::testing {

namespace {

using Rows = std::array<std::vector<std::vector<SimplexId>>, kNumRelations>;
using EdgeIds = std::map<std::array<SimplexId, 2>, SimplexId>;
using TriangleIds = std::map<std::array<SimplexId, 3>, SimplexId>;

// VL, EL, FL: each in the order of the star it comes from (VT, ET, FT, already filled).
void Links(const std::vector<std::array<SimplexId, 4>>& tets,
           const std::vector<std::array<SimplexId, 2>>& edges,
           const std::vector<std::array<SimplexId, 3>>& triangles, EdgeIds& edge_id,
           TriangleIds& triangle_id, Rows& R) {
  auto without = [&](SimplexId t, std::initializer_list<SimplexId> drop) {
    std::vector<SimplexId> rest;
    for (SimplexId v : tets[t])
      if (std::find(drop.begin(), drop.end(), v) == drop.end()) rest.push_back(v);
    return rest;
  };
  const auto& vt = R[Index(Relation::kVT)];
  const auto& et = R[Index(Relation::kET)];
  const auto& ft = R[Index(Relation::kFT)];
  auto& vl = R[Index(Relation::kVL)];
  auto& el = R[Index(Relation::kEL)];
  auto& fl = R[Index(Relation::kFL)];
  for (SimplexId v = 0; v < SimplexId(vt.size()); ++v) {
    for (SimplexId t : vt[v]) {
      auto r = without(t, {v});
      vl[v].push_back(triangle_id[{r[0], r[1], r[2]}]);
    }
  }
  for (SimplexId e = 0; e < SimplexId(edges.size()); ++e) {
    for (SimplexId t : et[e]) {
      auto r = without(t, {edges[e][0], edges[e][1]});
      el[e].push_back(edge_id[{r[0], r[1]}]);
    }
  }
  for (SimplexId f = 0; f < SimplexId(triangles.size()); ++f) {
    for (SimplexId t : ft[f]) {
      fl[f].push_back(without(t, {triangles[f][0], triangles[f][1], triangles[f][2]})[0]);
    }
  }
}

// VB, EB, FB: triangles in exactly one tetrahedron, and their faces (FT, FV, FE filled).
void Boundary(Rows& R) {
  const auto& ft = R[Index(Relation::kFT)];
  const auto& fv = R[Index(Relation::kFV)];
  const auto& fe = R[Index(Relation::kFE)];
  auto& vb = R[Index(Relation::kVB)];
  auto& eb = R[Index(Relation::kEB)];
  auto& fb = R[Index(Relation::kFB)];
  for (auto& row : vb) row = {0};
  for (auto& row : eb) row = {0};
  for (SimplexId f = 0; f < SimplexId(ft.size()); ++f) {
    const bool boundary = ft[f].size() == 1;
    fb[f] = {boundary ? 1 : 0};
    if (!boundary) continue;
    for (SimplexId v : fv[f]) vb[v] = {1};
    for (SimplexId e : fe[f]) eb[e] = {1};
  }
}

}  // namespace

RelationOracle::RelationOracle(const Topology& topology) {
  const SimplexId nv = topology.num_vertices();
  const SimplexId nt = topology.num_tetrahedra();
  std::vector<std::array<SimplexId, 4>> tets(nt);
  for (SimplexId t = 0; t < nt; ++t) {
    auto tv = topology.tetrahedron(t);
    tets[t] = {tv[0], tv[1], tv[2], tv[3]};
    std::sort(tets[t].begin(), tets[t].end());
  }
  std::set<std::array<SimplexId, 2>> edge_set;
  std::set<std::array<SimplexId, 3>> triangle_set;
  for (const auto& s : tets) {
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        edge_set.insert({s[i], s[j]});
        for (int k = j + 1; k < 4; ++k) triangle_set.insert({s[i], s[j], s[k]});
      }
  }
  edges_.assign(edge_set.begin(), edge_set.end());
  triangles_.assign(triangle_set.begin(), triangle_set.end());
  std::map<std::array<SimplexId, 2>, SimplexId> edge_id;
  std::map<std::array<SimplexId, 3>, SimplexId> triangle_id;
  for (size_t i = 0; i < edges_.size(); ++i) edge_id[edges_[i]] = SimplexId(i);
  for (size_t i = 0; i < triangles_.size(); ++i) triangle_id[triangles_[i]] = SimplexId(i);
  const SimplexId ne = SimplexId(edges_.size()), nf = SimplexId(triangles_.size());

  auto& R = rows_;
  auto sized = [&](Relation r, SimplexId n) -> std::vector<std::vector<SimplexId>>& {
    R[Index(r)].assign(n, {});
    return R[Index(r)];
  };
  auto& vv = sized(Relation::kVV, nv);
  auto& ve = sized(Relation::kVE, nv);
  auto& vf = sized(Relation::kVF, nv);
  auto& vt = sized(Relation::kVT, nv);
  auto& ev = sized(Relation::kEV, ne);
  auto& ef = sized(Relation::kEF, ne);
  auto& et = sized(Relation::kET, ne);
  auto& fv = sized(Relation::kFV, nf);
  auto& fe = sized(Relation::kFE, nf);
  auto& ft = sized(Relation::kFT, nf);
  auto& tv = sized(Relation::kTV, nt);
  auto& te = sized(Relation::kTE, nt);
  auto& tf = sized(Relation::kTF, nt);
  auto& tt = sized(Relation::kTT, nt);
  sized(Relation::kVL, nv);  // filled by Links
  sized(Relation::kEL, ne);  // filled by Links
  sized(Relation::kFL, nf);  // filled by Links
  sized(Relation::kVB, nv);  // filled by Boundary
  sized(Relation::kEB, ne);  // filled by Boundary
  sized(Relation::kFB, nf);  // filled by Boundary
  auto& ee = sized(Relation::kEE, ne);
  auto& ff = sized(Relation::kFF, nf);

  std::vector<std::set<SimplexId>> vv_set(nv), ve_set(nv), vf_set(nv), ef_set(ne), tt_set(nt);
  for (SimplexId e = 0; e < ne; ++e) {
    auto [a, b] = edges_[e];
    ev[e] = {a, b};
    vv_set[a].insert(b);
    vv_set[b].insert(a);
    ve_set[a].insert(e);
    ve_set[b].insert(e);
  }
  for (SimplexId f = 0; f < nf; ++f) {
    auto [a, b, c] = triangles_[f];
    fv[f] = {a, b, c};
    fe[f] = {edge_id[{a, b}], edge_id[{a, c}], edge_id[{b, c}]};
    for (SimplexId v : {a, b, c}) vf_set[v].insert(f);
    for (SimplexId e : fe[f]) ef_set[e].insert(f);
  }
  for (SimplexId t = 0; t < nt; ++t) {
    const auto& s = tets[t];
    tv[t] = {s[0], s[1], s[2], s[3]};
    te[t] = {edge_id[{s[0], s[1]}], edge_id[{s[0], s[2]}], edge_id[{s[0], s[3]}],
             edge_id[{s[1], s[2]}], edge_id[{s[1], s[3]}], edge_id[{s[2], s[3]}]};
    tf[t] = {triangle_id[{s[0], s[1], s[2]}], triangle_id[{s[0], s[1], s[3]}],
             triangle_id[{s[0], s[2], s[3]}], triangle_id[{s[1], s[2], s[3]}]};
    for (SimplexId v : s) vt[v].push_back(t);  // t ascending: rows come out sorted
    for (SimplexId e : te[t]) et[e].push_back(t);
    for (SimplexId f : tf[t]) ft[f].push_back(t);
  }
  for (SimplexId v = 0; v < nv; ++v) {
    vv[v].assign(vv_set[v].begin(), vv_set[v].end());
    ve[v].assign(ve_set[v].begin(), ve_set[v].end());
    vf[v].assign(vf_set[v].begin(), vf_set[v].end());
  }
  for (SimplexId e = 0; e < ne; ++e) ef[e].assign(ef_set[e].begin(), ef_set[e].end());
  // Neighbours through a shared vertex (edges) or edge (triangles).
  for (SimplexId e = 0; e < ne; ++e) {
    std::set<SimplexId> around;
    for (SimplexId v : edges_[e]) around.insert(ve_set[v].begin(), ve_set[v].end());
    around.erase(e);
    ee[e].assign(around.begin(), around.end());
  }
  for (SimplexId f = 0; f < nf; ++f) {
    std::set<SimplexId> around;
    for (SimplexId e : fe[f]) around.insert(ef_set[e].begin(), ef_set[e].end());
    around.erase(f);
    ff[f].assign(around.begin(), around.end());
  }
  for (SimplexId t = 0; t < nt; ++t) {
    for (SimplexId f : tf[t])
      for (SimplexId other : ft[f])
        if (other != t) tt_set[t].insert(other);
    tt[t].assign(tt_set[t].begin(), tt_set[t].end());
  }
  Links(tets, edges_, triangles_, edge_id, triangle_id, R);
  Boundary(R);
}

}  // namespace actopo::testing
