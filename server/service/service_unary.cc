// The unary RPCs of TopologyServiceImpl: bookkeeping answered at once on gRPC's thread, and the
// relation calls, handed to the relations executor (the slow mesh calls: service_meshes.cc).
#include <google/protobuf/stubs/common.h>
#include <grpcpp/grpcpp.h>

#include <chrono>

#include "absl/strings/str_cat.h"
#include "server/core/process_memory.h"
#include "server/core/status_macros.h"
#include "server/io/samples.h"
#include "server/io/vtk_reader.h"
#include "server/service/offload.h"
#include "server/service/service.h"
#include "server/service/wire.h"

namespace actopo::service {

TopologyServiceImpl::TopologyServiceImpl(MeshRegistry* meshes, SessionManager* sessions,
                                         UploadSpool* spool, MemoryBudget* budget, Metrics* metrics,
                                         ServiceLimits limits, ServiceThreads threads,
                                         std::string token,
                                         std::function<void(std::string_view)> before_work)
    : meshes_(meshes),
      sessions_(sessions),
      spool_(spool),
      budget_(budget),
      metrics_(metrics),
      limits_(limits),
      token_(std::move(token)),
      before_work_(std::move(before_work)),
      background_("actopo-load", threads.background),
      relations_("actopo-relation", threads.relations),
      jobs_("actopo-job", threads.jobs) {}

void TopologyServiceImpl::Drain() {
  draining_ = true;
  sessions_->Drain();
  for (Executor* executor : {&background_, &relations_, &jobs_}) executor->CancelAll();
}

void TopologyServiceImpl::BeforeWork(std::string_view rpc) {
  if (before_work_) before_work_(rpc);
}

absl::StatusOr<std::shared_ptr<Session>> TopologyServiceImpl::FindSession(const std::string& id) {
  return sessions_->Get(id);
}

absl::StatusOr<JobLease> TopologyServiceImpl::StartJob(const std::string& session_id,
                                                       Algorithm algorithm) {
  return sessions_->StartJob(session_id, algorithm);
}

void TopologyServiceImpl::RecordJob(std::string_view algorithm, std::string_view structure,
                                    double seconds, const EngineStats& engine) {
  metrics_->Job(algorithm, structure, seconds, engine);
}

absl::Status TopologyServiceImpl::Admit(grpc::CallbackServerContext* context) const {
  if (draining_) return absl::UnavailableError("the server is shutting down; retry elsewhere");
  if (token_.empty()) return absl::OkStatus();
  const auto& metadata = context->client_metadata();
  auto it = metadata.find("authorization");
  if (it == metadata.end() ||
      std::string_view(it->second.data(), it->second.size()) != "Bearer " + token_) {
    return absl::UnauthenticatedError(
        "authorization: missing or wrong bearer token (metadata 'authorization: Bearer TOKEN')");
  }
  return absl::OkStatus();
}

void TopologyServiceImpl::Count(std::string_view rpc, const absl::Status& status) {
  metrics_->Request(rpc, int(status.code()));
}

GaugeValues TopologyServiceImpl::Gauges() const {
  return {.meshes = int(meshes_->size()),
          .sessions = int(sessions_->size()),
          .budget_used_bytes = budget_->used(),
          .budget_limit_bytes = budget_->limit(),
          .process_rss_bytes = CurrentRssBytes(),
          .process_heap_bytes = HeapInUseBytes(),
          .engine_threads = sessions_->threads_in_use(),
          .uploads = spool_->size(),
          .upload_bytes = spool_->used_bytes()};
}

grpc::ServerUnaryReactor* TopologyServiceImpl::GetServerInfo(grpc::CallbackServerContext* c,
                                                             const v1::GetServerInfoRequest*,
                                                             v1::GetServerInfoResponse* out) {
  return Unary(c, "GetServerInfo", [&] {
    out->set_version("0.1.0");
    auto& libs = *out->mutable_library_versions();
    libs["grpc"] = grpc::Version();
    libs["protobuf"] = google::protobuf::internal::VersionString(GOOGLE_PROTOBUF_VERSION);
    libs["vtk"] = io::VtkVersion();
    for (Algorithm a : AllAlgorithms()) out->add_algorithms(std::string(AlgorithmName(a)));
    for (Relation r : AllRelations()) out->add_relations(std::string(RelationName(r)));
    for (const std::string& s : io::SampleNames()) out->add_samples(s);
    v1::ServerLimits* l = out->mutable_limits();
    l->set_max_batch_size(limits_.max_batch_size);
    l->set_max_message_bytes(limits_.max_message_bytes);
    l->set_memory_budget_bytes(budget_->limit());
    l->set_max_meshes(limits_.max_meshes);
    l->set_max_sessions(limits_.max_sessions);
    l->set_max_engine_threads(limits_.max_engine_threads);
    l->set_session_idle_timeout_seconds(limits_.session_idle_timeout_seconds);
    l->set_upload_budget_bytes(limits_.upload_budget_bytes);
    l->set_upload_timeout_seconds(limits_.upload_timeout_seconds);
    l->set_max_uploads(limits_.max_uploads);
    return absl::OkStatus();
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::ListMeshes(grpc::CallbackServerContext* c,
                                                          const v1::ListMeshesRequest*,
                                                          v1::ListMeshesResponse* out) {
  return Unary(c, "ListMeshes", [&] {
    for (const auto& m : meshes_->List()) {
      Fill(*m, sessions_->SessionsOnMesh(m->id), out->add_meshes());
    }
    return absl::OkStatus();
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::GetMesh(grpc::CallbackServerContext* c,
                                                       const v1::GetMeshRequest* in,
                                                       v1::GetMeshResponse* out) {
  const auto describe = [this, in, out](const Progress& progress) -> absl::Status {
    ASSIGN_OR_RETURN(auto mesh, meshes_->Get(in->mesh_id()));
    if (in->count_faces()) RETURN_IF_ERROR(mesh->EnsureFaces(progress));
    Fill(*mesh, sessions_->SessionsOnMesh(mesh->id), out->mutable_mesh());
    return absl::OkStatus();
  };
  // Building the faces takes seconds on a large mesh: not on gRPC's threads.
  if (in->count_faces()) return Offload(background_, c, "GetMesh", describe);
  return Unary(c, "GetMesh", [&] { return describe(Progress()); });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::DeleteMesh(grpc::CallbackServerContext* c,
                                                          const v1::DeleteMeshRequest* in,
                                                          v1::DeleteMeshResponse*) {
  // Sessions keep their mesh alive: its memory is freed when the last one closes.
  return Unary(c, "DeleteMesh", [&] { return meshes_->Delete(in->mesh_id()); });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::DeleteField(grpc::CallbackServerContext* c,
                                                           const v1::DeleteFieldRequest* in,
                                                           v1::DeleteFieldResponse* out) {
  // Sessions and jobs reading the field hold it: it is freed when the last one lets go.
  return Unary(c, "DeleteField", [&]() -> absl::Status {
    ASSIGN_OR_RETURN(auto mesh, meshes_->Get(in->mesh_id()));
    RETURN_IF_ERROR(mesh->fields.Delete(in->name()));
    Fill(*mesh, sessions_->SessionsOnMesh(mesh->id), out->mutable_mesh());
    return absl::OkStatus();
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::GetSession(grpc::CallbackServerContext* c,
                                                          const v1::GetSessionRequest* in,
                                                          v1::GetSessionResponse* out) {
  return Unary(c, "GetSession", [&]() -> absl::Status {
    ASSIGN_OR_RETURN(auto session, sessions_->Get(in->session_id()));
    Fill(*session, sessions_->RunningJob(session->id()), out->mutable_session());
    return absl::OkStatus();
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::ListSessions(grpc::CallbackServerContext* c,
                                                            const v1::ListSessionsRequest*,
                                                            v1::ListSessionsResponse* out) {
  return Unary(c, "ListSessions", [&] {
    for (const auto& s : sessions_->List()) {
      Fill(*s, sessions_->RunningJob(s->id()), out->add_sessions());
    }
    return absl::OkStatus();
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::CloseSession(grpc::CallbackServerContext* c,
                                                            const v1::CloseSessionRequest* in,
                                                            v1::CloseSessionResponse*) {
  return Unary(c, "CloseSession", [&]() -> absl::Status {
    // Its running job is cancelled; the job's stream ends with CANCELLED.
    return sessions_->Close(in->session_id());
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::GetSessionStats(grpc::CallbackServerContext* c,
                                                               const v1::GetSessionStatsRequest* in,
                                                               v1::GetSessionStatsResponse* out) {
  return Unary(c, "GetSessionStats", [&]() -> absl::Status {
    ASSIGN_OR_RETURN(auto session, sessions_->Get(in->session_id()));
    const SessionStats s = session->stats();
    Fill(s.engine, out->mutable_engine());
    Fill(s.memory, out->mutable_memory());
    out->mutable_memory()->set_process_rss_bytes(CurrentRssBytes());
    out->mutable_relation_queries()->set_count(s.queries);
    out->mutable_relation_queries()->set_ns(s.query_ns);
    out->mutable_jobs()->set_count(s.jobs);
    out->mutable_jobs()->set_ns(s.job_ns);
    out->set_preprocess_seconds(s.preprocess_seconds);
    v1::QueryBreakdown* b = out->mutable_query_breakdown();
    b->set_simplices(s.query_simplices);
    b->set_queue_ns(s.query_queue_ns);
    b->set_compute_ns(s.query_compute_ns);
    b->set_serialize_ns(s.query_serialize_ns);
    return absl::OkStatus();
  });
}

absl::Status TopologyServiceImpl::AnswerRelation(const std::string& session_id,
                                                 v1::Relation relation, const v1::Simplex& simplex,
                                                 bool include_vertices, std::vector<int64_t>& ids,
                                                 std::vector<int64_t>* vertices,
                                                 const Progress& stop) {
  ASSIGN_OR_RETURN(auto session, sessions_->Get(session_id));
  ASSIGN_OR_RETURN(Relation r, FromProto(relation));
  // The first query on the mesh that reads edges or triangles builds them, for every session.
  if (NeedsFaces(r)) RETURN_IF_ERROR(session->mesh().EnsureFaces(stop));
  const int dim = SourceDimension(r);
  SimplexId s = -1;
  switch (simplex.simplex_case()) {
    case v1::Simplex::kId: {
      ASSIGN_OR_RETURN(s, session->ResolveId(dim, simplex.id(), "simplex.id"));
      break;
    }
    case v1::Simplex::kVertices: {
      const auto& v = simplex.vertices().ids();
      ASSIGN_OR_RETURN(s,
                       session->ResolveVertices(dim, std::span<const int64_t>(v.data(), v.size()),
                                                "simplex.vertices"));
      break;
    }
    default: return absl::InvalidArgumentError("simplex: set id or vertices");
  }
  session->Query(r, s, ids, include_vertices ? vertices : nullptr);
  return absl::OkStatus();
}

grpc::ServerUnaryReactor* TopologyServiceImpl::GetRelation(grpc::CallbackServerContext* c,
                                                           const v1::GetRelationRequest* in,
                                                           v1::GetRelationResponse* out) {
  return Offload(relations_, c, "GetRelation",
                 [this, in, out](const Progress& stop) -> absl::Status {
                   std::vector<int64_t> ids, vertices;
                   RETURN_IF_ERROR(AnswerRelation(in->session_id(), in->relation(), in->simplex(),
                                                  in->include_vertices(), ids, &vertices, stop));
                   out->mutable_ids()->Add(ids.begin(), ids.end());
                   out->mutable_vertices()->Add(vertices.begin(), vertices.end());
                   return absl::OkStatus();
                 });
}

absl::Status TopologyServiceImpl::AnswerBatch(const std::string& session_id, v1::Relation relation,
                                              const v1::Array* ids, const v1::Array* vertex_tuples,
                                              v1::Array* offsets_out, v1::Array* values_out,
                                              std::vector<ItemFailure>* failures,
                                              const Progress& stop) {
  ASSIGN_OR_RETURN(auto session, sessions_->Get(session_id));
  ASSIGN_OR_RETURN(Relation r, FromProto(relation));
  // The first query on the mesh that reads edges or triangles builds them, for every session.
  if (NeedsFaces(r)) RETURN_IF_ERROR(session->mesh().EnsureFaces(stop));
  const int dim = SourceDimension(r);
  const bool by_tuple = vertex_tuples != nullptr;
  if (by_tuple == (ids != nullptr)) {
    return absl::InvalidArgumentError("ids / vertex_tuples: set exactly one of them");
  }
  const char* field = by_tuple ? "vertex_tuples" : "ids";
  ASSIGN_OR_RETURN(std::vector<int64_t> flat,
                   UnpackIntegers(by_tuple ? *vertex_tuples : *ids, field));
  const int k = by_tuple ? dim + 1 : 1;
  if (by_tuple && (vertex_tuples->shape_size() != 2 || vertex_tuples->shape(1) != k)) {
    return absl::InvalidArgumentError(
        absl::StrCat("vertex_tuples.shape: must be (n, ", k, ") for ", RelationName(r).data()));
  }
  const int64_t n = int64_t(flat.size()) / k;
  if (n > limits_.max_batch_size) {
    return absl::ResourceExhaustedError(absl::StrCat(
        field, ": ", n, " simplices exceed the batch limit of ", limits_.max_batch_size,
        "; split the batch (StreamRelations takes many batches on one call)"));
  }
  // Resolved items are answered in runs between failed ones, one reader per run.
  std::vector<int64_t> offsets = {0}, values;
  offsets.reserve(n + 1);
  std::vector<SimplexId> run;
  run.reserve(n);
  for (int64_t i = 0; i < n; ++i) {
    absl::StatusOr<SimplexId> s =
        by_tuple ? session->ResolveVertices(dim, std::span(flat).subspan(i * k, k), {field, i})
                 : session->ResolveId(dim, flat[i], {field, i});
    if (s.ok()) {
      run.push_back(*s);
      continue;
    }
    if (failures == nullptr) return s.status();
    session->Query(r, run, offsets, values);
    run.clear();
    offsets.push_back(int64_t(values.size()));  // an empty row
    failures->push_back({i, s.status()});
  }
  session->Query(r, run, offsets, values);
  // Refused here with a message that says what to do, not by gRPC's "larger than max".
  const int64_t answer_bytes = int64_t(offsets.size() + values.size()) * int64_t(sizeof(int64_t));
  if (answer_bytes > limits_.max_message_bytes) {
    return absl::ResourceExhaustedError(absl::StrCat(
        field, ": the answer for these ", n, " simplices takes ", answer_bytes >> 20,
        " MiB, more than the server's message limit of ", limits_.max_message_bytes >> 20,
        " MiB; send fewer per call (StreamRelations takes many batches on one call)"));
  }
  const auto start = std::chrono::steady_clock::now();
  Pack("offsets", offsets, offsets_out);
  Pack("values", values, values_out);
  session->AddQuerySerializeTime(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start)
          .count());
  return absl::OkStatus();
}

grpc::ServerUnaryReactor* TopologyServiceImpl::GetRelationBatch(
    grpc::CallbackServerContext* c, const v1::GetRelationBatchRequest* in,
    v1::GetRelationBatchResponse* out) {
  return Offload(relations_, c, "GetRelationBatch", [this, in, out](const Progress& stop) {
    return AnswerBatch(in->session_id(), in->relation(), in->has_ids() ? &in->ids() : nullptr,
                       in->has_vertex_tuples() ? &in->vertex_tuples() : nullptr,
                       out->mutable_offsets(), out->mutable_values(), nullptr, stop);
  });
}

grpc::ServerUnaryReactor* TopologyServiceImpl::CancelJob(grpc::CallbackServerContext* c,
                                                         const v1::CancelJobRequest* in,
                                                         v1::CancelJobResponse*) {
  return Unary(c, "CancelJob", [&] { return sessions_->CancelJob(in->job_id()); });
}

}  // namespace actopo::service
