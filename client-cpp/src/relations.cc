// Relation queries: one simplex, batches (split by the server's max_batch_size and merged), and
// the bidirectional stream.
#include <mutex>
#include <thread>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "src/internal/convert.h"
#include "src/internal/core.h"
#include "src/internal/names.h"

namespace actopo {
namespace {

using Stream = grpc::ClientReaderWriter<v1::StreamRelationsRequest, v1::StreamRelationsResponse>;

void SetSimplex(const Simplex& simplex, v1::Simplex* out) {
  if (simplex.by_vertices()) {
    out->mutable_vertices()->mutable_ids()->Add(simplex.vertices().begin(),
                                                simplex.vertices().end());
  } else {
    out->set_id(simplex.id());
  }
}

StreamItem ToItem(const v1::StreamRelationsResponse& response) {
  StreamItem item;
  item.request_id = response.request_id();
  if (response.has_error() && response.error().code() != 0) {
    item.ids = absl::Status(static_cast<absl::StatusCode>(response.error().code()),
                            response.error().message());
  } else {
    item.ids = std::vector<int64_t>(response.ids().begin(), response.ids().end());
  }
  return item;
}

absl::StatusOr<v1::GetRelationResponse> Single(internal::Core& core, std::string_view session_id,
                                                std::string_view relation, const Simplex& simplex,
                                                bool include_vertices) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  v1::GetRelationRequest request;
  request.set_session_id(std::string(session_id));
  request.set_relation(r);
  SetSimplex(simplex, request.mutable_simplex());
  request.set_include_vertices(include_vertices);
  return core.Unary(&v1::TopologyService::Stub::GetRelation, request, core.QuickContext());
}

// Appends one batch answer to `csr`, checking the server kept the CSR promises.
absl::Status Merge(const v1::GetRelationBatchResponse& response, size_t expected,
                   RelationCsr& csr) {
  ACTOPO_ASSIGN_OR_RETURN(std::vector<int64_t> offsets,
                          internal::UnpackInt64(response.offsets(), "offsets"));
  ACTOPO_ASSIGN_OR_RETURN(std::vector<int64_t> values,
                          internal::UnpackInt64(response.values(), "values"));
  if (offsets.size() != expected + 1 || offsets.front() != 0 ||
      offsets.back() != int64_t(values.size())) {
    return absl::InternalError(absl::StrCat(
        "offsets: the server sent ", offsets.size(), " offsets ending at ",
        offsets.empty() ? 0 : offsets.back(), " for ", expected, " simplices and ",
        values.size(), " values"));
  }
  const int64_t base = int64_t(csr.values.size());
  if (csr.offsets.empty()) csr.offsets.push_back(0);
  for (size_t i = 1; i < offsets.size(); ++i) {
    if (offsets[i] < offsets[i - 1]) {
      return absl::InternalError("offsets: the server sent decreasing offsets");
    }
    csr.offsets.push_back(base + offsets[i]);
  }
  csr.values.insert(csr.values.end(), values.begin(), values.end());
  return absl::OkStatus();
}

// A batch of ids (tuple_size 0) or vertex tuples, `batch` simplices per request.
absl::StatusOr<RelationCsr> Batch(internal::Core& core, std::string_view session_id,
                                  v1::Relation relation, std::span<const int64_t> values,
                                  int tuple_size, size_t batch) {
  const size_t k = tuple_size == 0 ? 1 : size_t(tuple_size);
  const size_t n = values.size() / k;
  RelationCsr csr{.offsets = {0}};
  for (size_t first = 0; first < n; first += batch) {
    const size_t count = std::min(n - first, batch);
    v1::GetRelationBatchRequest request;
    request.set_session_id(std::string(session_id));
    request.set_relation(relation);
    const std::span<const int64_t> part = values.subspan(first * k, count * k);
    if (tuple_size == 0) {
      const int64_t shape[] = {int64_t(count)};
      internal::PackInt64(part, shape, request.mutable_ids());
    } else {
      const int64_t shape[] = {int64_t(count), int64_t(k)};
      internal::PackInt64(part, shape, request.mutable_vertex_tuples());
    }
    ACTOPO_ASSIGN_OR_RETURN(v1::GetRelationBatchResponse response,
                            core.Unary(&v1::TopologyService::Stub::GetRelationBatch, request,
                                       core.QuickContext()));
    ACTOPO_RETURN_IF_ERROR(Merge(response, count, csr));
  }
  return csr;
}

// Sends requests 0..n-1 (`fill` sets each simplex) on a writer thread and hands the answers to
// `on_item` on this one.
absl::Status StreamAll(internal::Core& core, std::string_view session_id,
                       std::string_view relation, size_t n,
                       const std::function<void(size_t, v1::Simplex*)>& fill,
                       const std::function<void(StreamItem)>& on_item) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  if (n == 0) return absl::OkStatus();
  std::unique_ptr<grpc::ClientContext> context = core.Context(std::chrono::milliseconds(0));
  std::unique_ptr<Stream> stream = core.stub->StreamRelations(context.get());
  std::thread writer([&] {
    v1::StreamRelationsRequest request;
    request.set_session_id(std::string(session_id));
    request.set_relation(r);
    for (size_t i = 0; i < n; ++i) {
      request.set_request_id(int64_t(i));
      request.clear_simplex();
      fill(i, request.mutable_simplex());
      if (!stream->Write(request)) return;  // the call ended; Finish says why
    }
    stream->WritesDone();
  });
  v1::StreamRelationsResponse response;
  try {
    while (stream->Read(&response)) on_item(ToItem(response));
  } catch (...) {  // from on_item: stop the call and the writer before the stack unwinds
    context->TryCancel();
    while (stream->Read(&response)) {
    }
    writer.join();
    stream->Finish();
    throw;
  }
  writer.join();
  return internal::FromGrpc(stream->Finish());
}

}  // namespace

absl::StatusOr<std::vector<int64_t>> Client::Relation(std::string_view session_id,
                                                      std::string_view relation,
                                                      const Simplex& simplex) {
  ACTOPO_ASSIGN_OR_RETURN(v1::GetRelationResponse response,
                          Single(*core_, session_id, relation, simplex, false));
  return std::vector<int64_t>(response.ids().begin(), response.ids().end());
}

absl::StatusOr<RelationResult> Client::RelationWithVertices(std::string_view session_id,
                                                            std::string_view relation,
                                                            const Simplex& simplex) {
  ACTOPO_ASSIGN_OR_RETURN(v1::GetRelationResponse response,
                          Single(*core_, session_id, relation, simplex, true));
  return RelationResult{.ids = {response.ids().begin(), response.ids().end()},
                        .vertices = {response.vertices().begin(), response.vertices().end()}};
}

absl::StatusOr<RelationCsr> Client::RelationBatch(std::string_view session_id,
                                                  std::string_view relation,
                                                  std::span<const int64_t> ids) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  if (ids.empty()) return RelationCsr{.offsets = {0}};
  ACTOPO_ASSIGN_OR_RETURN(const int64_t batch, MaxBatchSize());
  return Batch(*core_, session_id, r, ids, 0, size_t(batch));
}

absl::StatusOr<RelationCsr> Client::RelationBatchByVertices(std::string_view session_id,
                                                            std::string_view relation,
                                                            std::span<const int64_t> tuples,
                                                            int tuple_size) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  if (tuple_size < 1 || tuple_size > 4 || tuples.size() % size_t(tuple_size) != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("tuples: ", tuples.size(), " vertex ids do not make tuples of ",
                     tuple_size, " (1 to 4 vertices per simplex)"));
  }
  if (tuples.empty()) return RelationCsr{.offsets = {0}};
  ACTOPO_ASSIGN_OR_RETURN(const int64_t batch, MaxBatchSize());
  return Batch(*core_, session_id, r, tuples, tuple_size, size_t(batch));
}

absl::Status Client::StreamRelations(std::string_view session_id, std::string_view relation,
                                     std::span<const int64_t> ids,
                                     const std::function<void(StreamItem)>& on_item) {
  return StreamAll(
      *core_, session_id, relation, ids.size(),
      [ids](size_t i, v1::Simplex* s) { s->set_id(ids[i]); }, on_item);
}

absl::Status Client::StreamRelations(std::string_view session_id, std::string_view relation,
                                     std::span<const Simplex> simplices,
                                     const std::function<void(StreamItem)>& on_item) {
  return StreamAll(
      *core_, session_id, relation, simplices.size(),
      [simplices](size_t i, v1::Simplex* s) { SetSimplex(simplices[i], s); }, on_item);
}

// ---------------------------------------------------------------------------------------------
// RelationStream.

struct RelationStream::Impl {
  std::shared_ptr<internal::Core> core;  // keeps the channel alive as long as the stream
  std::unique_ptr<grpc::ClientContext> context;
  std::unique_ptr<Stream> stream;
  std::mutex mu;  // guards the flags below (the writer and the reader may be two threads)
  bool writes_done = false;
  bool write_failed = false;
  bool reads_done = false;
  std::optional<absl::Status> final_status;
};

RelationStream::RelationStream(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

RelationStream::~RelationStream() {
  if (!impl_->final_status) Finish().IgnoreError();
}

absl::Status RelationStream::Write(int64_t request_id, std::string_view session_id,
                                   std::string_view relation, const Simplex& simplex) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (impl_->writes_done || impl_->write_failed) {
      return absl::FailedPreconditionError(
          "stream: no more writes (WritesDone was called or the call ended; Finish says why)");
    }
  }
  v1::StreamRelationsRequest request;
  request.set_request_id(request_id);
  request.set_session_id(std::string(session_id));
  request.set_relation(r);
  SetSimplex(simplex, request.mutable_simplex());
  if (!impl_->stream->Write(request)) {
    std::lock_guard<std::mutex> lock(impl_->mu);
    impl_->write_failed = true;
    return absl::FailedPreconditionError("stream: the call ended; Finish says why");
  }
  return absl::OkStatus();
}

absl::Status RelationStream::WritesDone() {
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    if (impl_->writes_done) return absl::OkStatus();
    impl_->writes_done = true;
  }
  if (!impl_->stream->WritesDone()) {
    return absl::FailedPreconditionError("stream: the call ended; Finish says why");
  }
  return absl::OkStatus();
}

std::optional<StreamItem> RelationStream::Read() {
  v1::StreamRelationsResponse response;
  if (!impl_->stream->Read(&response)) {
    std::lock_guard<std::mutex> lock(impl_->mu);
    impl_->reads_done = true;
    return std::nullopt;
  }
  return ToItem(response);
}

absl::Status RelationStream::Finish() {
  if (impl_->final_status) return *impl_->final_status;
  bool reads_done, writes_done;
  {
    std::lock_guard<std::mutex> lock(impl_->mu);
    reads_done = impl_->reads_done;
    writes_done = impl_->writes_done;
  }
  if (!reads_done) {
    // Answers nobody will read: give up on the call rather than wait for them.
    impl_->context->TryCancel();
    v1::StreamRelationsResponse ignored;
    while (impl_->stream->Read(&ignored)) {
    }
  }
  if (!writes_done) WritesDone().IgnoreError();
  impl_->final_status = internal::FromGrpc(impl_->stream->Finish());
  return *impl_->final_status;
}

void RelationStream::Cancel() { impl_->context->TryCancel(); }

absl::StatusOr<std::unique_ptr<RelationStream>> Client::OpenRelationStream() {
  auto impl = std::make_unique<RelationStream::Impl>();
  impl->core = core_;
  impl->context = core_->Context(std::chrono::milliseconds(0));
  impl->stream = core_->stub->StreamRelations(impl->context.get());
  return std::make_unique<RelationStream>(std::move(impl));
}

}  // namespace actopo
