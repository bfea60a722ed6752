#include "server/core/trace.h"

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <utility>

namespace actopo {
namespace {

std::atomic<uint64_t> next_trace_id{1};

std::string& RoleSlot() {
  thread_local std::string role;
  return role;
}

// The calling thread's buffer in the recorder it used last.
struct Cached {
  uint64_t trace = 0;
  void* buffer = nullptr;
};
thread_local Cached cached;

int64_t Nanos(Trace::Clock::duration d) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(d).count();
}

// A JSON string literal of `s` (names are ours; roles may hold anything).
void WriteString(std::ostream& out, std::string_view s) {
  out << '"';
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out << '\\' << c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", c);
      out << escaped;
    } else {
      out << c;
    }
  }
  out << '"';
}

// Microseconds with nanosecond precision, as the format wants.
void WriteMicros(std::ostream& out, int64_t ns) {
  char text[32];
  std::snprintf(text, sizeof text, "%" PRId64 ".%03d", ns / 1000, int(ns % 1000));
  out << text;
}

}  // namespace

void SetThreadRole(std::string role) { RoleSlot() = std::move(role); }

const std::string& ThreadRole() { return RoleSlot(); }

Trace::Trace(int64_t max_events)
    : max_events_(max_events), id_(next_trace_id.fetch_add(1)), origin_(Clock::now()) {}

Trace::~Trace() = default;

Trace::ThreadBuffer& Trace::Buffer() {
  if (cached.trace == id_) return *static_cast<ThreadBuffer*>(cached.buffer);
  const std::thread::id self = std::this_thread::get_id();
  MutexLock lock(mu_);
  auto it = std::find_if(buffers_.begin(), buffers_.end(),
                         [&](const auto& b) { return b->thread == self; });
  if (it == buffers_.end()) {
    auto buffer = std::make_unique<ThreadBuffer>();
    buffer->thread = self;
    buffer->tid = int(buffers_.size()) + 1;
    buffer->role = ThreadRole().empty() ? "thread " + std::to_string(buffer->tid) : ThreadRole();
    buffers_.push_back(std::move(buffer));
    it = buffers_.end() - 1;
  }
  cached = {id_, it->get()};
  return **it;
}

void Trace::Add(const Event& event) {
  if (reserved_.fetch_add(1, std::memory_order_relaxed) >= max_events_) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  ThreadBuffer& buffer = Buffer();
  MutexLock lock(buffer.mu);
  buffer.events.push_back(event);
}

void Trace::Span(const char* name, const char* category, Clock::time_point start,
                 Clock::time_point end, const Args& args) {
  Add({name, category, Nanos(start - origin_), Nanos(end - start), args});
}

void Trace::Instant(const char* name, const char* category, const Args& args) {
  Add({name, category, Nanos(Clock::now() - origin_), -1, args});
}

int64_t Trace::events() const {
  return std::min(reserved_.load(std::memory_order_relaxed), max_events_);
}

void Trace::WriteJson(std::ostream& out) const {
  MutexLock lock(mu_);
  out << "{\"displayTimeUnit\":\"ms\",\"traceEvents\":[\n";
  bool first = true;
  const auto next = [&] {
    if (!first) out << ",\n";
    first = false;
  };
  next();
  out << R"({"ph":"M","pid":1,"tid":0,"name":"process_name","args":{"name":"actopo"}})";
  for (const auto& buffer : buffers_) {
    next();
    out << R"({"ph":"M","pid":1,"tid":)" << buffer->tid
        << R"(,"name":"thread_name","args":{"name":)";
    WriteString(out, buffer->role);
    out << "}}";
  }
  for (const auto& buffer : buffers_) {
    MutexLock events_lock(buffer->mu);
    for (const Event& e : buffer->events) {
      next();
      out << R"({"ph":")" << (e.duration_ns < 0 ? "i" : "X") << R"(","pid":1,"tid":)" << buffer->tid
          << ",\"name\":";
      WriteString(out, e.name);
      out << ",\"cat\":";
      WriteString(out, e.category);
      out << ",\"ts\":";
      WriteMicros(out, e.start_ns);
      if (e.duration_ns >= 0) {
        out << ",\"dur\":";
        WriteMicros(out, e.duration_ns);
      } else {
        out << R"(,"s":"t")";
      }
      if (e.args.block >= 0 || e.args.relation != nullptr || e.args.count >= 0) {
        out << ",\"args\":{";
        const char* sep = "";
        if (e.args.block >= 0) {
          out << "\"block\":" << e.args.block;
          sep = ",";
        }
        if (e.args.relation != nullptr) {
          out << sep << "\"relation\":";
          WriteString(out, e.args.relation);
          sep = ",";
        }
        if (e.args.count >= 0) out << sep << "\"count\":" << e.args.count;
        out << '}';
      }
      out << '}';
    }
  }
  out << "\n],\"otherData\":{\"events\":" << events() << ",\"dropped\":" << dropped()
      << ",\"max_events\":" << max_events_ << "}}\n";
}

}  // namespace actopo
