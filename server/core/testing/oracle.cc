#include "server/core/testing/oracle.h"

#include <algorithm>
#include <map>
#include <set>

namespace actopo::testing {

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
  auto& vl = sized(Relation::kVL, nv);
  auto& el = sized(Relation::kEL, ne);
  auto& fl = sized(Relation::kFL, nf);
  auto& vb = sized(Relation::kVB, nv);
  auto& eb = sized(Relation::kEB, ne);
  auto& fb = sized(Relation::kFB, nf);
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
  // Links, in the order of the star they come from.
  auto without = [&](SimplexId t, std::initializer_list<SimplexId> drop) {
    std::vector<SimplexId> rest;
    for (SimplexId v : tets[t])
      if (std::find(drop.begin(), drop.end(), v) == drop.end()) rest.push_back(v);
    return rest;
  };
  for (SimplexId v = 0; v < nv; ++v) {
    for (SimplexId t : vt[v]) {
      auto r = without(t, {v});
      vl[v].push_back(triangle_id[{r[0], r[1], r[2]}]);
    }
  }
  for (SimplexId e = 0; e < ne; ++e) {
    for (SimplexId t : et[e]) {
      auto r = without(t, {edges_[e][0], edges_[e][1]});
      el[e].push_back(edge_id[{r[0], r[1]}]);
    }
  }
  for (SimplexId f = 0; f < nf; ++f) {
    for (SimplexId t : ft[f]) {
      fl[f].push_back(without(t, {triangles_[f][0], triangles_[f][1], triangles_[f][2]})[0]);
    }
  }
  // Boundary: triangles in exactly one tetrahedron, and their faces.
  for (SimplexId v = 0; v < nv; ++v) vb[v] = {0};
  for (SimplexId e = 0; e < ne; ++e) eb[e] = {0};
  for (SimplexId f = 0; f < nf; ++f) {
    const bool boundary = ft[f].size() == 1;
    fb[f] = {boundary ? 1 : 0};
    if (!boundary) continue;
    for (SimplexId v : fv[f]) vb[v] = {1};
    for (SimplexId e : fe[f]) eb[e] = {1};
  }
}

}  // namespace actopo::testing
