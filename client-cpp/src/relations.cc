// Relation queries: one simplex, batches (split by the server's max_batch_size and merged), and
// the bidirectional stream.
#include <algorithm>
#include <mutex>
#include <thread>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"
#include "src/internal/convert.h"
#include "src/internal/core.h"
#include "src/internal/names.h"

namespace actopo::client {
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

absl::Status ToStatus(const v1::ItemError& error) {
  return absl::Status(static_cast<absl::StatusCode>(error.code()), error.message());
}

// Checks a CSR answer for `expected` simplices (the server's promises) and unpacks it.
absl::StatusOr<RelationCsr> ToCsr(const v1::Array& offsets_array, const v1::Array& values_array,
                                  size_t expected) {
  RelationCsr csr;
  ACTOPO_ASSIGN_OR_RETURN(csr.offsets, internal::UnpackInt64(offsets_array, "offsets"));
  ACTOPO_ASSIGN_OR_RETURN(csr.values, internal::UnpackInt64(values_array, "values"));
  const std::vector<int64_t>& o = csr.offsets;
  if ((expected != size_t(-1) && o.size() != expected + 1) || o.empty() || o.front() != 0 ||
      o.back() != int64_t(csr.values.size()) || !std::is_sorted(o.begin(), o.end())) {
    return absl::InternalError(absl::StrCat(
        "offsets: the server sent ", o.size(), " offsets ending at ", o.empty() ? 0 : o.back(),
        " for ", expected, " simplices and ", csr.values.size(), " values"));
  }
  return csr;
}

StreamItem ToItem(const v1::StreamRelationsResponse& response) {
  StreamItem item;
  item.request_id = response.request_id();
  if (response.has_error() && response.error().code() != 0) {
    item.ids = ToStatus(response.error());
  } else if (response.has_offsets()) {
    item.ids = std::vector<int64_t>();
    absl::StatusOr<RelationCsr> rows = ToCsr(response.offsets(), response.values(), size_t(-1));
    if (rows.ok()) {
      item.rows = std::move(*rows);
    } else {
      item.ids = rows.status();
    }
    for (const v1::ItemError& e : response.item_errors()) {
      item.item_errors.push_back({e.index(), ToStatus(e)});
    }
  } else {
    item.ids = std::vector<int64_t>(response.ids().begin(), response.ids().end());
  }
  return item;
}

// `count` simplices of `values` (ids, or tuples of tuple_size ids) into a request's array.
void SetBatch(std::span<const int64_t> part, size_t count, int tuple_size,
              v1::StreamRelationsRequest* request) {
  request->clear_ids();  // a reused request: PackInt64 appends to the shape
  request->clear_vertex_tuples();
  if (tuple_size == 0) {
    const int64_t shape[] = {int64_t(count)};
    internal::PackInt64(part, shape, request->mutable_ids());
  } else {
    const int64_t shape[] = {int64_t(count), int64_t(tuple_size)};
    internal::PackInt64(part, shape, request->mutable_vertex_tuples());
  }
}

// Appends `part` (the rows of simplices first, first + 1, ...) to `csr`.
void Append(const RelationCsr& part, RelationCsr& csr) {
  const int64_t base = int64_t(csr.values.size());
  for (size_t i = 1; i < part.offsets.size(); ++i) csr.offsets.push_back(base + part.offsets[i]);
  csr.values.insert(csr.values.end(), part.values.begin(), part.values.end());
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

// Sends requests 0..n-1 on a writer thread (`fill` sets what each carries besides its id, session
// and relation) and hands the answers to `on_response` on this one, until it returns false (the
// call is then cancelled). The status is the call's; CANCELLED after a stop.
absl::Status StreamRequests(
    internal::Core& core, std::string_view session_id, v1::Relation relation, size_t n,
    const std::function<void(size_t, v1::StreamRelationsRequest*)>& fill,
    const std::function<bool(const v1::StreamRelationsResponse&)>& on_response) {
  if (n == 0) return absl::OkStatus();
  std::unique_ptr<grpc::ClientContext> context = core.Context(std::chrono::milliseconds(0));
  std::unique_ptr<Stream> stream = core.stub->StreamRelations(context.get());
  std::thread writer([&] {
    v1::StreamRelationsRequest request;
    request.set_session_id(std::string(session_id));
    request.set_relation(relation);
    for (size_t i = 0; i < n; ++i) {
      request.set_request_id(int64_t(i));
      fill(i, &request);
      if (!stream->Write(request)) return;  // the call ended; Finish says why
    }
    stream->WritesDone();
  });
  // Stops the call and the writer (before the stack unwinds, on an exception from on_response).
  const auto stop = [&] {
    context->TryCancel();
    v1::StreamRelationsResponse ignored;
    while (stream->Read(&ignored)) {
    }
  };
  v1::StreamRelationsResponse response;
  try {
    while (stream->Read(&response)) {
      if (!on_response(response)) {
        stop();
        break;
      }
    }
  } catch (...) {
    stop();
    writer.join();
    stream->Finish();
    throw;
  }
  writer.join();
  return internal::FromGrpc(stream->Finish());
}

constexpr size_t kStreamChunk = 65536;

// A batch of ids (tuple_size 0) or vertex tuples: one GetRelationBatch call when it fits one
// stream chunk and `batch` (a larger answer could pass the message limit), else chunks on one
// stream, written by a second thread ahead of the answers.
absl::StatusOr<RelationCsr> Batch(internal::Core& core, std::string_view session_id,
                                  v1::Relation relation, std::span<const int64_t> values,
                                  int tuple_size, size_t batch) {
  const size_t k = tuple_size == 0 ? 1 : size_t(tuple_size);
  const size_t n = values.size() / k;
  if (n <= std::min(batch, kStreamChunk)) {
    v1::GetRelationBatchRequest request;
    request.set_session_id(std::string(session_id));
    request.set_relation(relation);
    const int64_t shape[] = {int64_t(n), int64_t(k)};
    internal::PackInt64(values, std::span<const int64_t>(shape, tuple_size == 0 ? 1 : 2),
                        tuple_size == 0 ? request.mutable_ids() : request.mutable_vertex_tuples());
    ACTOPO_ASSIGN_OR_RETURN(
        v1::GetRelationBatchResponse response,
        core.Unary(&v1::TopologyService::Stub::GetRelationBatch, request, core.QuickContext()));
    return ToCsr(response.offsets(), response.values(), n);
  }
  const size_t chunk = std::min(batch, kStreamChunk);
  const size_t chunks = (n + chunk - 1) / chunk;
  RelationCsr csr{.offsets = {0}};
  absl::Status status;  // of the first chunk that failed
  size_t answered = 0;  // chunks
  const absl::Status call = StreamRequests(
      core, session_id, relation, chunks,
      [&](size_t c, v1::StreamRelationsRequest* request) {
        const size_t first = c * chunk, count = std::min(chunk, n - first);
        SetBatch(values.subspan(first * k, count * k), count, tuple_size, request);
      },
      [&](const v1::StreamRelationsResponse& response) {
        const size_t first = answered++ * chunk, count = std::min(chunk, n - first);
        if (response.has_error() && response.error().code() != 0) {
          status = ToStatus(response.error());
        } else if (response.item_errors_size() > 0) {
          const v1::ItemError& e = response.item_errors(0);
          status = absl::Status(
              static_cast<absl::StatusCode>(e.code()),
              absl::StrCat(e.message(), " (simplex ", first + size_t(e.index()), " of the input)"));
        } else {
          absl::StatusOr<RelationCsr> part = ToCsr(response.offsets(), response.values(), count);
          if (part.ok()) Append(*part, csr);
          status = part.status();
        }
        return status.ok();
      });
  if (!status.ok()) return status;
  if (!call.ok()) return call;
  if (csr.size() != n) {
    return absl::InternalError(
        absl::StrCat("stream: the server answered ", csr.size(), " of ", n, " simplices"));
  }
  return csr;
}

// One simplex per request (`fill` sets each), answers to `on_item`.
absl::Status StreamAll(internal::Core& core, std::string_view session_id, std::string_view relation,
                       size_t n, const std::function<void(size_t, v1::Simplex*)>& fill,
                       const std::function<void(StreamItem)>& on_item) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  return StreamRequests(
      core, session_id, r, n,
      [&](size_t i, v1::StreamRelationsRequest* request) {
        request->clear_simplex();
        fill(i, request->mutable_simplex());
      },
      [&](const v1::StreamRelationsResponse& response) {
        on_item(ToItem(response));
        return true;
      });
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
    return absl::InvalidArgumentError(absl::StrCat("tuples: ", tuples.size(),
                                                   " vertex ids do not make tuples of ", tuple_size,
                                                   " (1 to 4 vertices per simplex)"));
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

  absl::Status Send(const v1::StreamRelationsRequest& request) {
    {
      std::lock_guard<std::mutex> lock(mu);
      if (writes_done || write_failed) {
        return absl::FailedPreconditionError(
            "stream: no more writes (WritesDone was called or the call ended; Finish says why)");
      }
    }
    if (!stream->Write(request)) {
      std::lock_guard<std::mutex> lock(mu);
      write_failed = true;
      return absl::FailedPreconditionError("stream: the call ended; Finish says why");
    }
    return absl::OkStatus();
  }
};

RelationStream::RelationStream(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

RelationStream::~RelationStream() {
  if (!impl_->final_status) Finish().IgnoreError();
}

absl::Status RelationStream::Write(int64_t request_id, std::string_view session_id,
                                   std::string_view relation, const Simplex& simplex) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  v1::StreamRelationsRequest request;
  request.set_request_id(request_id);
  request.set_session_id(std::string(session_id));
  request.set_relation(r);
  SetSimplex(simplex, request.mutable_simplex());
  return impl_->Send(request);
}

absl::Status RelationStream::WriteBatch(int64_t request_id, std::string_view session_id,
                                        std::string_view relation, std::span<const int64_t> values,
                                        int tuple_size) {
  ACTOPO_ASSIGN_OR_RETURN(v1::Relation r, internal::RelationFromName(relation));
  if (tuple_size < 0 || tuple_size > 4 || (tuple_size > 0 && values.size() % tuple_size != 0)) {
    return absl::InvalidArgumentError(absl::StrCat("values: ", values.size(),
                                                   " vertex ids do not make tuples of ", tuple_size,
                                                   " (0 for ids, 1 to 4 vertices per simplex)"));
  }
  v1::StreamRelationsRequest request;
  request.set_request_id(request_id);
  request.set_session_id(std::string(session_id));
  request.set_relation(r);
  SetBatch(values, values.size() / std::max(tuple_size, 1), tuple_size, &request);
  return impl_->Send(request);
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

}  // namespace actopo::client
