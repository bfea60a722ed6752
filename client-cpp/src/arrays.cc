// The small value types of the public header: arrays, enum names, simplices, cancel tokens.
#include <cstring>
#include <mutex>

#include "absl/strings/str_cat.h"
#include "actopo/client.h"

namespace actopo::client {
namespace {

template <class T>
T Load(const char* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

}  // namespace

std::string_view DataTypeName(DataType dtype) {
  switch (dtype) {
    case DataType::kFloat32: return "float32";
    case DataType::kFloat64: return "float64";
    case DataType::kInt8: return "int8";
    case DataType::kInt32: return "int32";
    case DataType::kInt64: return "int64";
    case DataType::kUint8: return "uint8";
    case DataType::kUnspecified: break;
  }
  return "unspecified";
}

size_t DataTypeSize(DataType dtype) {
  switch (dtype) {
    case DataType::kInt8:
    case DataType::kUint8: return 1;
    case DataType::kFloat32:
    case DataType::kInt32: return 4;
    case DataType::kFloat64:
    case DataType::kInt64: return 8;
    case DataType::kUnspecified: break;
  }
  return 0;
}

int64_t Array::size() const {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  return n;
}

absl::Status Array::CheckLayout(DataType want) const {
  if (dtype != want) {
    return absl::InvalidArgumentError(absl::StrCat("array '", name, "': dtype is ",
                                                   std::string(DataTypeName(dtype)), ", not ",
                                                   std::string(DataTypeName(want))));
  }
  const int64_t n = size();
  if (n < 0 || data.size() != size_t(n) * DataTypeSize(dtype)) {
    return absl::InvalidArgumentError(absl::StrCat("array '", name, "': ", data.size(),
                                                   " bytes do not hold ", n, " ",
                                                   std::string(DataTypeName(dtype)), " values"));
  }
  return absl::OkStatus();
}

std::vector<double> Array::ToDouble() const {
  const size_t width = DataTypeSize(dtype);
  if (width == 0) return {};
  std::vector<double> values(data.size() / width);
  const char* p = data.data();
  for (size_t i = 0; i < values.size(); ++i, p += width) {
    switch (dtype) {
      case DataType::kFloat32: values[i] = Load<float>(p); break;
      case DataType::kFloat64: values[i] = Load<double>(p); break;
      case DataType::kInt8: values[i] = Load<int8_t>(p); break;
      case DataType::kInt32: values[i] = Load<int32_t>(p); break;
      case DataType::kInt64: values[i] = double(Load<int64_t>(p)); break;
      case DataType::kUint8: values[i] = Load<uint8_t>(p); break;
      case DataType::kUnspecified: break;
    }
  }
  return values;
}

absl::StatusOr<std::vector<int64_t>> Array::ToInt64() const {
  if (dtype == DataType::kFloat32 || dtype == DataType::kFloat64 ||
      dtype == DataType::kUnspecified) {
    return absl::InvalidArgumentError(absl::StrCat(
        "array '", name, "': dtype ", std::string(DataTypeName(dtype)), " is not an integer type"));
  }
  const size_t width = DataTypeSize(dtype);
  std::vector<int64_t> values(data.size() / width);
  const char* p = data.data();
  for (size_t i = 0; i < values.size(); ++i, p += width) {
    switch (dtype) {
      case DataType::kInt8: values[i] = Load<int8_t>(p); break;
      case DataType::kInt32: values[i] = Load<int32_t>(p); break;
      case DataType::kInt64: values[i] = Load<int64_t>(p); break;
      case DataType::kUint8: values[i] = Load<uint8_t>(p); break;
      default: break;
    }
  }
  return values;
}

std::string_view StructureName(Structure structure) {
  switch (structure) {
    case Structure::kExplicit: return "explicit";
    case Structure::kCompact: return "compact";
    case Structure::kActopo: break;
  }
  return "actopo";
}

std::string_view PrefetchName(Prefetch prefetch) {
  switch (prefetch) {
    case Prefetch::kLinear: return "linear";
    case Prefetch::kSpatial: return "spatial";
    case Prefetch::kAdaptive: return "adaptive";
    case Prefetch::kAuto: break;
  }
  return "auto";
}

std::string_view PrecomputeName(Precompute precompute) {
  switch (precompute) {
    case Precompute::kRequested: return "requested";
    case Precompute::kDeclared: return "declared";
    case Precompute::kAuto: break;
  }
  return "auto";
}

Simplex Simplex::Vertices(std::vector<int64_t> vertices) {
  Simplex s;
  s.by_vertices_ = true;
  s.vertices_ = std::move(vertices);
  return s;
}

const Array* ResultArrays::Find(std::string_view name) const {
  auto it = arrays.find(name);
  return it == arrays.end() ? nullptr : &it->second;
}

// A token's state: the flag and the callbacks of the calls it may cancel.
struct CancelToken::State {
  std::mutex mu;
  bool cancelled = false;
  int64_t next_id = 0;
  std::map<int64_t, std::function<void()>> callbacks;
};

// Removes its callback on destruction, so a finished call is never cancelled late.
class CancelToken::Registration {
 public:
  Registration(std::shared_ptr<State> state, int64_t id) : state_(std::move(state)), id_(id) {}
  ~Registration() {
    std::lock_guard<std::mutex> lock(state_->mu);
    state_->callbacks.erase(id_);
  }

 private:
  std::shared_ptr<State> state_;
  int64_t id_;
};

CancelToken::CancelToken() : state_(std::make_shared<State>()) {}

void CancelToken::Cancel() const {
  std::lock_guard<std::mutex> lock(state_->mu);
  if (state_->cancelled) return;
  state_->cancelled = true;
  // Under the lock: a registration cannot go away (and its call end) while its callback runs.
  for (auto& [id, f] : state_->callbacks) f();
}

bool CancelToken::cancelled() const {
  std::lock_guard<std::mutex> lock(state_->mu);
  return state_->cancelled;
}

std::shared_ptr<CancelToken::Registration> CancelToken::OnCancel(std::function<void()> f) const {
  std::lock_guard<std::mutex> lock(state_->mu);
  if (state_->cancelled) {
    f();
    return nullptr;
  }
  const int64_t id = state_->next_id++;
  state_->callbacks.emplace(id, std::move(f));
  return std::make_shared<Registration>(state_, id);
}

}  // namespace actopo::client
