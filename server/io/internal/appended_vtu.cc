#include "server/io/internal/appended_vtu.h"

#include <fcntl.h>
#include <libdeflate.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "server/core/parallel.h"
#include "server/core/status_macros.h"
#include "server/io/internal/xml_tags.h"

namespace actopo::io::internal {
namespace {

constexpr char kPhase[] = "read";
constexpr uint8_t kVtkTetra = 10;
// The XML before the appended data is a few kilobytes; a file whose markup runs on is not one
// of ours.
constexpr size_t kMaxHeaderBytes = size_t(16) << 20;
// Uncompressed arrays are converted in pieces of this many bytes (a multiple of every scalar
// size), so they spread over the threads as compressed blocks do.
constexpr size_t kRawPiece = size_t(1) << 20;

// A whole file, mapped read-only; empty when it cannot be.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
      void* p = ::mmap(nullptr, size_t(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
      if (p != MAP_FAILED) {
        data_ = static_cast<const uint8_t*>(p);
        size_ = size_t(st.st_size);
        ::madvise(p, size_, MADV_WILLNEED);  // the blocks are read in parallel, out of order
      }
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (data_ != nullptr) ::munmap(const_cast<uint8_t*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  const uint8_t* data() const { return data_; }
  size_t size() const { return size_; }

  // Takes the pages wholly below `upto` out of the process's resident set: they are clean file
  // pages, read again from the file (or the page cache) should anyone touch them after.
  void Release(const uint8_t* upto) {
    const size_t page = size_t(::sysconf(_SC_PAGESIZE));
    const size_t end = std::min(size_t(upto - data_), size_) / page * page;
    if (end <= released_) return;
    ::madvise(const_cast<uint8_t*>(data_) + released_, end - released_, MADV_DONTNEED);
    released_ = end;
  }
  std::string_view text() const { return {reinterpret_cast<const char*>(data_), size_}; }

 private:
  const uint8_t* data_ = nullptr;
  size_t size_ = 0;
  size_t released_ = 0;  // bytes from the start taken out by Release
};

enum class Scalar {
  kInt8,
  kUInt8,
  kInt16,
  kUInt16,
  kInt32,
  kUInt32,
  kInt64,
  kUInt64,
  kFloat32,
  kFloat64
};

std::optional<Scalar> ScalarNamed(std::string_view name) {
  static constexpr std::pair<std::string_view, Scalar> kNames[] = {
      {"Int8", Scalar::kInt8},      {"UInt8", Scalar::kUInt8},   {"Int16", Scalar::kInt16},
      {"UInt16", Scalar::kUInt16},  {"Int32", Scalar::kInt32},   {"UInt32", Scalar::kUInt32},
      {"Int64", Scalar::kInt64},    {"UInt64", Scalar::kUInt64}, {"Float32", Scalar::kFloat32},
      {"Float64", Scalar::kFloat64}};
  for (const auto& [n, s] : kNames) {
    if (n == name) return s;
  }
  return std::nullopt;
}

// Calls fn(T{}) with the C++ type of `s`.
template <class Fn>
auto VisitScalar(Scalar s, Fn&& fn) {
  switch (s) {
    case Scalar::kInt8: return fn(int8_t{});
    case Scalar::kUInt8: return fn(uint8_t{});
    case Scalar::kInt16: return fn(int16_t{});
    case Scalar::kUInt16: return fn(uint16_t{});
    case Scalar::kInt32: return fn(int32_t{});
    case Scalar::kUInt32: return fn(uint32_t{});
    case Scalar::kInt64: return fn(int64_t{});
    case Scalar::kUInt64: return fn(uint64_t{});
    case Scalar::kFloat32: return fn(float{});
    case Scalar::kFloat64: break;
  }
  return fn(double{});
}

size_t ScalarBytes(Scalar s) {
  return VisitScalar(s, [](auto t) { return sizeof t; });
}

template <class T>
T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);  // the appended data has no alignment
  return v;
}

struct ArraySpec {
  Scalar scalar = Scalar::kFloat64;
  std::string_view name;
  int components = 1;
  uint64_t offset = 0;
};

struct Layout {
  bool wide_header = false;  // header_type UInt64
  bool zlib = false;
  int64_t num_points = -1, num_cells = -1;
  std::optional<ArraySpec> points, connectivity, offsets, types;
  std::vector<ArraySpec> point_data;
  size_t appended = 0;  // the first byte after the appended section's '_'
};

// The array a DataArray tag describes, if it lies in the appended section.
std::optional<ArraySpec> AppendedArray(const XmlTag& tag) {
  ArraySpec spec;
  const std::optional<Scalar> scalar = ScalarNamed(tag.Get("type"));
  if (!tag.self_closing || tag.Get("format") != "appended" || !scalar) return std::nullopt;
  spec.scalar = *scalar;
  spec.name = tag.Get("Name");
  const std::string_view components = tag.Get("NumberOfComponents");
  if (!components.empty() && (!ParseXmlInt(components, &spec.components) || spec.components < 1)) {
    return std::nullopt;
  }
  if (spec.name.empty() || !ParseXmlInt(tag.Get("offset"), &spec.offset)) return std::nullopt;
  // Values are taken as written; VTK's parser decodes entities and turns whitespace into spaces.
  // A name where the two would differ goes to VTK, so that fields are named as VTK names them.
  if (spec.name.find_first_of("&\t\n\r") != std::string_view::npos) return std::nullopt;
  return spec;
}

// The file's layout, if it is the one this reader reads.
std::optional<Layout> ParseLayout(const MappedFile& file) {
  const std::string_view text = file.text().substr(0, kMaxHeaderBytes);
  Layout layout;
  size_t pos = 0;
  XmlTag tag;
  std::string_view section;  // the open PointData, CellData, Points, Cells or FieldData
  int pieces = 0;
  bool vtk_file = false;
  // Closing tags carry their name without the '/': every opening test says !tag.closing.
  while (NextXmlTag(text, pos, tag) == XmlScan::kTag) {
    if (tag.name == "VTKFile" && !tag.closing) {
      const std::string_view header = tag.Get("header_type");
      const std::string_view compressor = tag.Get("compressor");
      if (tag.Get("type") != "UnstructuredGrid" || tag.Get("byte_order") != "LittleEndian" ||
          (header != "" && header != "UInt32" && header != "UInt64") ||
          (compressor != "" && compressor != "vtkZLibDataCompressor")) {
        return std::nullopt;
      }
      layout.wide_header = header == "UInt64";
      layout.zlib = !compressor.empty();
      vtk_file = true;
    } else if (tag.name == "Piece" && !tag.closing) {
      if (++pieces > 1 || !ParseXmlInt(tag.Get("NumberOfPoints"), &layout.num_points) ||
          !ParseXmlInt(tag.Get("NumberOfCells"), &layout.num_cells)) {
        return std::nullopt;
      }
    } else if (!tag.closing &&
               (tag.name == "PointData" || tag.name == "CellData" || tag.name == "Points" ||
                tag.name == "Cells" || tag.name == "FieldData")) {
      if (!tag.self_closing) section = tag.name;
    } else if (tag.closing && tag.name == section) {
      section = {};
    } else if (tag.name == "DataArray" && !tag.closing &&
               (section == "PointData" || section == "Points" || section == "Cells")) {
      // Cell data and field data are not read (VTK's path drops them too); their inline
      // values, if any, hold no '<' for NextXmlTag to trip on.
      std::optional<ArraySpec> spec = AppendedArray(tag);
      if (!spec) return std::nullopt;  // inline data: VTK's reader
      if (section == "PointData") {
        for (const ArraySpec& other : layout.point_data) {
          if (other.name == spec->name) return std::nullopt;  // VTK keeps one of the two
        }
        layout.point_data.push_back(*spec);
      } else if (section == "Points") {
        if (layout.points) return std::nullopt;
        layout.points = spec;
      } else if (section == "Cells") {
        std::optional<ArraySpec>* slot = spec->name == "connectivity" ? &layout.connectivity
                                         : spec->name == "offsets"    ? &layout.offsets
                                         : spec->name == "types"      ? &layout.types
                                                                      : nullptr;
        if (slot == nullptr || slot->has_value()) return std::nullopt;
        *slot = spec;
      }
    } else if (tag.name == "AppendedData" && !tag.closing) {
      if (tag.Get("encoding") != "raw") return std::nullopt;
      const size_t underscore = file.text().find('_', pos);
      if (underscore == std::string_view::npos) return std::nullopt;
      layout.appended = underscore + 1;
      break;
    }
  }
  if (!vtk_file || pieces != 1 || layout.appended == 0 || !layout.points || !layout.connectivity ||
      !layout.offsets || !layout.types || layout.points->components != 3 ||
      layout.types->scalar != Scalar::kUInt8 || layout.num_points < 1 ||
      layout.num_points > INT32_MAX || layout.num_cells < 1 || layout.num_cells > INT32_MAX) {
    return std::nullopt;
  }
  return layout;
}

// Takes `count` scalars that start at scalar `first` of their array; false when they are not
// what the reader accepts (the file then goes to VTK).
using Sink = std::function<bool(const uint8_t* bytes, size_t count, uint64_t first)>;

// Sinks write into vectors sized only once every array's header has been checked against the
// file, so a header that lies about the sizes allocates nothing.
template <class T>
Sink ToDouble(std::vector<double>* out) {
  return [out](const uint8_t* bytes, size_t count, uint64_t first) {
    double* values = out->data() + first;
    for (size_t i = 0; i < count; ++i) values[i] = double(Load<T>(bytes + i * sizeof(T)));
    return true;
  };
}

template <class T>
Sink Connectivity(std::vector<SimplexId>* tetrahedra, int64_t num_points) {
  return [tetrahedra, num_points](const uint8_t* bytes, size_t count, uint64_t first) {
    SimplexId* out = tetrahedra->data();
    for (size_t i = 0; i < count; ++i) {
      const T id = Load<T>(bytes + i * sizeof(T));
      if constexpr (std::is_signed_v<T>) {
        if (id < 0) return false;
      }
      if (uint64_t(id) >= uint64_t(num_points)) return false;
      out[first + i] = SimplexId(id);
    }
    return true;
  };
}

// Cell k ends at 4 (k + 1): every cell has four points.
template <class T>
Sink FourPointCells() {
  return [](const uint8_t* bytes, size_t count, uint64_t first) {
    for (size_t i = 0; i < count; ++i) {
      if (uint64_t(Load<T>(bytes + i * sizeof(T))) != 4 * (first + i + 1)) return false;
    }
    return true;
  };
}

bool AllTetrahedra(const uint8_t* bytes, size_t count, uint64_t) {
  return std::all_of(bytes, bytes + count, [](uint8_t t) { return t == kVtkTetra; });
}

// A piece of an array's data: inflated (zlib) or taken as it is, then given to its sink.
struct Block {
  const Sink* sink;
  const uint8_t* source;
  size_t source_bytes;
  size_t bytes;    // uncompressed
  uint64_t first;  // index of its first scalar in the array
  size_t scalar_bytes;
  bool compressed;
};

// Appends the blocks of `spec`'s data, which must hold `scalars` values; false when its header
// does not fit the file or disagrees with that size.
bool PlanArray(const MappedFile& file, const Layout& layout, const ArraySpec& spec,
               uint64_t scalars, const Sink* sink, std::vector<Block>& blocks) {
  const size_t word = layout.wide_header ? 8 : 4;
  const size_t scalar_bytes = ScalarBytes(spec.scalar);
  const uint64_t expected = scalars * scalar_bytes;
  const auto read_word = [&](uint64_t at, uint64_t& value) {
    if (at > file.size() || file.size() - at < word) return false;
    value = word == 8 ? Load<uint64_t>(file.data() + at) : Load<uint32_t>(file.data() + at);
    return true;
  };
  uint64_t at = uint64_t(layout.appended) + spec.offset;
  if (!layout.zlib) {
    uint64_t bytes = 0;
    if (!read_word(at, bytes) || bytes != expected || file.size() - (at + word) < bytes) {
      return false;
    }
    const uint8_t* data = file.data() + at + word;
    for (uint64_t done = 0; done < bytes; done += kRawPiece) {
      const size_t n = size_t(std::min<uint64_t>(kRawPiece, bytes - done));
      blocks.push_back({sink, data + done, n, n, done / scalar_bytes, scalar_bytes, false});
    }
    return true;
  }
  uint64_t count = 0, block_bytes = 0, last_bytes = 0;
  if (!read_word(at, count) || !read_word(at + word, block_bytes) ||
      !read_word(at + 2 * word, last_bytes)) {
    return false;
  }
  // Sizes are checked before they are multiplied: no product below can wrap around.
  if (count > file.size() / word || block_bytes == 0 || block_bytes % scalar_bytes != 0 ||
      last_bytes > block_bytes || (count > 1 && count - 1 > expected / block_bytes)) {
    return false;
  }
  const uint64_t total =
      count == 0 ? 0 : (count - 1) * block_bytes + (last_bytes ? last_bytes : block_bytes);
  if (total != expected) return false;
  uint64_t source = at + (3 + count) * word;
  for (uint64_t b = 0; b < count; ++b) {
    uint64_t compressed = 0;
    if (!read_word(at + (3 + b) * word, compressed) || source > file.size() ||
        file.size() - source < compressed) {
      return false;
    }
    const uint64_t first_byte = b * block_bytes;
    const uint64_t bytes = std::min(block_bytes, total - first_byte);
    // Deflate expands at most 1032-fold: a block claiming more holds a lie.
    if (bytes > compressed * 1032 + 64) return false;
    blocks.push_back({sink, file.data() + source, size_t(compressed), size_t(bytes),
                      first_byte / scalar_bytes, scalar_bytes, true});
    source += compressed;
  }
  return true;
}

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

// Inflates and converts every block on `threads` threads, in windows between which progress is
// reported; OK(false) when a block fails (corrupt data, or values the reader refuses). After each
// window, the file's pages below every block still to come leave the resident set, so with
// `blocks` in file order the mapped file never stands whole beside the mesh it becomes.
absl::StatusOr<bool> RunBlocks(MappedFile& file, const std::vector<Block>& blocks, int threads,
                               const Progress& progress) {
  threads = std::max(threads, 1);
  size_t scratch_bytes = 0;
  for (const Block& b : blocks) {
    if (b.compressed) scratch_bytes = std::max(scratch_bytes, b.bytes);
  }
  std::vector<std::vector<uint8_t>> scratch(threads);
  std::vector<std::unique_ptr<libdeflate_decompressor, DecompressorDeleter>> inflaters(threads);
  for (int t = 0; t < threads; ++t) {
    inflaters[t].reset(libdeflate_alloc_decompressor());
    if (inflaters[t] == nullptr) return absl::ResourceExhaustedError("read: no memory to inflate");
    scratch[t].resize(scratch_bytes);
  }
  std::atomic<bool> failed{false};
  const int64_t n = int64_t(blocks.size());
  // lowest[i]: the lowest byte any of blocks i.. reads (arrays may lie in any order).
  std::vector<const uint8_t*> lowest(n + 1, file.data() + file.size());
  for (int64_t i = n - 1; i >= 0; --i) lowest[i] = std::min(lowest[i + 1], blocks[i].source);
  const int64_t window = std::max<int64_t>(1, n / 64);
  for (int64_t begin = 0; begin < n; begin += window) {
    const int64_t end = std::min(n, begin + window);
    ParallelFor(end - begin, threads, [&](int64_t i, int thread) {
      if (failed.load(std::memory_order_relaxed)) return;
      const Block& b = blocks[begin + i];
      const uint8_t* bytes = b.source;
      if (b.compressed) {
        size_t out = 0;
        if (libdeflate_zlib_decompress(inflaters[thread].get(), b.source, b.source_bytes,
                                       scratch[thread].data(), b.bytes,
                                       &out) != LIBDEFLATE_SUCCESS ||
            out != b.bytes) {
          failed = true;
          return;
        }
        bytes = scratch[thread].data();
      }
      if (!(*b.sink)(bytes, b.bytes / b.scalar_bytes, b.first)) failed = true;
    });
    if (failed) return false;
    file.Release(lowest[end]);
    RETURN_IF_ERROR(progress.Update(kPhase, 0.9 * double(end) / double(n)));
  }
  return true;
}

}  // namespace

absl::StatusOr<std::optional<Mesh>> ReadAppendedVtu(const std::string& path, int threads,
                                                    const Progress& progress) {
  static_assert(std::endian::native == std::endian::little, "the fast path reads little-endian");
  MappedFile file(path);
  if (file.data() == nullptr) return std::nullopt;
  const std::optional<Layout> layout = ParseLayout(file);
  if (!layout) return std::nullopt;

  Mesh mesh;
  const uint64_t np = uint64_t(layout->num_points), nc = uint64_t(layout->num_cells);
  // Sinks live here, blocks point at them; the fields' vectors must not move.
  mesh.point_fields.reserve(layout->point_data.size());
  std::vector<std::unique_ptr<Sink>> sinks;
  std::vector<Block> blocks;
  const auto plan = [&](const ArraySpec& spec, uint64_t scalars, Sink sink) {
    sinks.push_back(std::make_unique<Sink>(std::move(sink)));
    return PlanArray(file, *layout, spec, scalars, sinks.back().get(), blocks);
  };
  bool ok = plan(*layout->points, 3 * np, VisitScalar(layout->points->scalar, [&](auto t) {
    return ToDouble<decltype(t)>(&mesh.points);
  }));
  const Scalar id_type = layout->connectivity->scalar;
  const bool integer_ids = id_type != Scalar::kFloat32 && id_type != Scalar::kFloat64;
  ok = ok && integer_ids && layout->offsets->scalar != Scalar::kFloat32 &&
       layout->offsets->scalar != Scalar::kFloat64;
  if (!ok) return std::nullopt;
  ok = plan(*layout->connectivity, 4 * nc,
            VisitScalar(id_type,
                        [&](auto t) -> Sink {
                          if constexpr (std::is_integral_v<decltype(t)>) {
                            return Connectivity<decltype(t)>(&mesh.tetrahedra, layout->num_points);
                          }
                          return nullptr;
                        })) &&
       plan(*layout->offsets, nc,
            VisitScalar(layout->offsets->scalar,
                        [&](auto t) -> Sink {
                          if constexpr (std::is_integral_v<decltype(t)>)
                            return FourPointCells<decltype(t)>();
                          return nullptr;
                        })) &&
       plan(*layout->types, nc, AllTetrahedra);
  for (const ArraySpec& spec : layout->point_data) {
    // Vectors and tensors are not scalar fields: skipped, as the VTK path skips them.
    if (!ok || spec.components != 1) continue;
    PointField field;
    field.name = std::string(spec.name);
    field.is_integer = spec.scalar != Scalar::kFloat32 && spec.scalar != Scalar::kFloat64;
    field.source_bytes = int8_t(ScalarBytes(spec.scalar) <= 4 ? 4 : 8);
    mesh.point_fields.push_back(std::move(field));
    std::vector<double>* values = &mesh.point_fields.back().values;
    ok = plan(spec, np,
              VisitScalar(spec.scalar, [&](auto t) { return ToDouble<decltype(t)>(values); }));
  }
  if (!ok) return std::nullopt;
  // In file order, so that the pages of the file already read leave the resident set window by
  // window: VTK writes the point data first, and read last, those few pages would keep the
  // whole file resident until the end, raising the load's peak.
  std::sort(blocks.begin(), blocks.end(),
            [](const Block& a, const Block& b) { return a.source < b.source; });
  mesh.points.resize(3 * np);
  mesh.tetrahedra.resize(4 * nc);
  for (PointField& field : mesh.point_fields) field.values.resize(np);
  ASSIGN_OR_RETURN(const bool converted, RunBlocks(file, blocks, threads, progress));
  if (!converted) return std::nullopt;
  if (absl::Status s = ValidateMesh(mesh); !s.ok()) {
    return absl::Status(s.code(), absl::StrCat(path, ": ", s.message()));
  }
  return mesh;
}

}  // namespace actopo::io::internal
