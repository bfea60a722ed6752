#include "server/service/field_decoder.h"

#include <cmath>
#include <cstring>
#include <limits>

#include "gmock/gmock.h"
#include "gtest/gtest.h"
#include "server/core/testing/status.h"

namespace actopo::service {
namespace {

using ::testing::HasSubstr;

template <class T>
std::string Bytes(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

v1::AddFieldsHeader Header(std::vector<std::pair<std::string, v1::DataType>> fields,
                           const std::string& data = {}) {
  v1::AddFieldsHeader h;
  h.set_mesh_id("mesh-1");
  for (const auto& [name, dtype] : fields) {
    v1::UploadField* f = h.add_fields();
    f->set_name(name);
    f->set_dtype(dtype);
  }
  if (!data.empty()) h.set_sha256(Sha256Hex(data));
  return h;
}

TEST(FieldDecoder, DecodesFieldsFromChunksOfAnySize) {
  const std::vector<float> a = {0.5f, -1.25f, 3};
  const std::vector<double> b = {1e300, 2, -7.5};
  const std::string data = Bytes(a) + Bytes(b);
  for (size_t chunk : {size_t(1), size_t(3), size_t(5), size_t(8), data.size()}) {
    auto decoder = FieldDecoder::Start(
        Header({{"a", v1::DATA_TYPE_FLOAT32}, {"b", v1::DATA_TYPE_FLOAT64}}, data), 3);
    ASSERT_TRUE(decoder.ok()) << decoder.status();
    EXPECT_EQ(decoder->expected_bytes(), data.size());
    for (size_t at = 0; at < data.size(); at += chunk) {
      ASSERT_TRUE(decoder->Append(std::string_view(data).substr(at, chunk)).ok());
    }
    const auto fields = decoder->Finish();
    ASSERT_TRUE(fields.ok()) << fields.status();
    ASSERT_EQ(fields->size(), 2u);
    EXPECT_EQ((*fields)[0].name, "a");
    EXPECT_EQ((*fields)[0].values, (std::vector<double>{0.5, -1.25, 3}));
    EXPECT_EQ((*fields)[0].source_bytes, 4);
    EXPECT_EQ((*fields)[1].values, b);
    EXPECT_EQ((*fields)[1].source_bytes, 8);
  }
}

TEST(FieldDecoder, RefusesBadHeadersNamingTheField) {
  auto message = [](const v1::AddFieldsHeader& h) {
    const auto d = FieldDecoder::Start(h, 4);
    EXPECT_EQ(d.status().code(), absl::StatusCode::kInvalidArgument);
    return std::string(d.status().message());
  };
  EXPECT_THAT(message(Header({})), HasSubstr("header.fields: no field announced"));
  EXPECT_THAT(message(Header({{"", v1::DATA_TYPE_FLOAT64}})),
              HasSubstr("header.fields[0].name: empty"));
  EXPECT_THAT(message(Header({{"x", v1::DATA_TYPE_FLOAT64}, {"x", v1::DATA_TYPE_FLOAT32}})),
              HasSubstr("header.fields[1].name: 'x' is announced twice"));
  EXPECT_THAT(message(Header({{"x", v1::DATA_TYPE_INT32}})),
              HasSubstr("header.fields[0].dtype: DATA_TYPE_INT32 is not FLOAT32 or FLOAT64"));
  v1::AddFieldsHeader h = Header({{"x", v1::DATA_TYPE_FLOAT64}});
  h.set_sha256("abc");
  EXPECT_THAT(message(h), HasSubstr("header.sha256: expected 64 lowercase hex digits"));
  h = Header({{"x", v1::DATA_TYPE_FLOAT64}});
  h.mutable_fields(0)->set_time(std::numeric_limits<double>::quiet_NaN());
  EXPECT_THAT(message(h), HasSubstr("header.fields[0].time: nan is not finite"));
}

TEST(FieldDecoder, RefusesBadDataNamingFieldAndVertex) {
  const std::vector<double> good = {1, 2, 3};
  auto start = [](const std::string& data) {
    return OkValue(FieldDecoder::Start(
        Header({{"a", v1::DATA_TYPE_FLOAT64}, {"b", v1::DATA_TYPE_FLOAT64}}, data), 3));
  };
  // A non-finite value of the second field.
  const std::vector<double> bad = {0, std::nan(""), 1};
  FieldDecoder d = start(Bytes(good) + Bytes(bad));
  const absl::Status nan = d.Append(Bytes(good) + Bytes(bad));
  EXPECT_EQ(nan.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_THAT(nan.message(), HasSubstr("fields[1] 'b': vertex 1 has value nan"));
  // Too many bytes, too few, and bytes other than announced.
  d = start(Bytes(good) + Bytes(good));
  EXPECT_THAT(d.Append(Bytes(good) + Bytes(good) + "x").message(),
              HasSubstr("chunk: received more than the 48 bytes the header announced"));
  d = start(Bytes(good) + Bytes(good));
  ASSERT_TRUE(d.Append(Bytes(good)).ok());
  EXPECT_THAT(d.Finish().status().message(),
              HasSubstr("chunk: the stream ended after 24 of the 48 bytes the header announced, "
                        "in fields[1] 'b' after 0 of its 3 values"));
  d = start(Bytes(good) + Bytes(good));
  ASSERT_TRUE(d.Append(Bytes(good) + Bytes(std::vector<double>{1, 2, 4})).ok());
  EXPECT_EQ(d.Finish().status().code(), absl::StatusCode::kDataLoss);
}

TEST(FieldDecoder, WithoutAChecksumTheBytesAreNotHashed) {
  const std::vector<double> values = {4, 5};
  FieldDecoder d = OkValue(FieldDecoder::Start(Header({{"a", v1::DATA_TYPE_FLOAT64}}), 2));
  ASSERT_TRUE(d.Append(Bytes(values)).ok());
  EXPECT_EQ((*d.Finish())[0].values, values);
}

TEST(FieldDecoder, TheDigestMayComeAfterTheChunks) {
  const std::vector<double> values = {4, 5, std::ldexp(1.0, -1074)};
  const std::string data = Bytes(values);
  v1::AddFieldsHeader h = Header({{"a", v1::DATA_TYPE_FLOAT64}});
  h.set_sha256_last(true);
  FieldDecoder d = OkValue(FieldDecoder::Start(h, 3));
  ASSERT_TRUE(d.Append(data.substr(0, 7)).ok());
  ASSERT_TRUE(d.Append(data.substr(7)).ok());
  ASSERT_TRUE(d.SetDigest(Sha256Hex(data)).ok());
  EXPECT_THAT(d.Append("x").message(), HasSubstr("chunk: after the sha256"));
  const auto fields = d.Finish();
  ASSERT_TRUE(fields.ok()) << fields.status();
  EXPECT_EQ((*fields)[0].values, values);
  // A wrong digest, none, a malformed one, one without sha256_last, one given twice.
  d = OkValue(FieldDecoder::Start(h, 3));
  ASSERT_TRUE(d.Append(data).ok());
  ASSERT_TRUE(d.SetDigest(Sha256Hex("other")).ok());
  EXPECT_EQ(d.Finish().status().code(), absl::StatusCode::kDataLoss);
  d = OkValue(FieldDecoder::Start(h, 3));
  ASSERT_TRUE(d.Append(data).ok());
  EXPECT_THAT(d.Finish().status().message(), HasSubstr("sha256_last); none came"));
  d = OkValue(FieldDecoder::Start(h, 3));
  EXPECT_THAT(d.SetDigest(std::string(64, 'A')).message(),
              HasSubstr("sha256: expected 64 lowercase hex digits"));
  d = OkValue(FieldDecoder::Start(Header({{"a", v1::DATA_TYPE_FLOAT64}}), 3));
  EXPECT_THAT(d.SetDigest(Sha256Hex(data)).message(), HasSubstr("needs header.sha256_last"));
  h.set_sha256(Sha256Hex(data));
  EXPECT_THAT(FieldDecoder::Start(h, 3).status().message(),
              HasSubstr("with sha256_last also set; send the digest once"));
}

TEST(FieldDecoder, ABadValueDeepInAChunkIsNamedByItsVertex) {
  // Many values in one chunk, unaligned in it, float32 and float64: the bad one is found.
  for (const int offset : {0, 1, 3}) {
    std::vector<float> a(1000, 1.5f);
    a[777] = std::numeric_limits<float>::infinity();
    const std::string data = std::string(size_t(offset), 'p') + Bytes(a);
    FieldDecoder d = OkValue(FieldDecoder::Start(Header({{"a", v1::DATA_TYPE_FLOAT32}}), 1000));
    EXPECT_THAT(d.Append(std::string_view(data).substr(size_t(offset))).message(),
                HasSubstr("fields[0] 'a': vertex 777 has value inf"));
    std::vector<double> b(1000, -2.0);
    b[999] = -std::numeric_limits<double>::infinity();
    const std::string more = std::string(size_t(offset), 'p') + Bytes(b);
    d = OkValue(FieldDecoder::Start(Header({{"b", v1::DATA_TYPE_FLOAT64}}), 1000));
    ASSERT_TRUE(d.Append(std::string_view(more).substr(size_t(offset), 8 * 500 + 3)).ok());
    EXPECT_THAT(d.Append(std::string_view(more).substr(size_t(offset) + 8 * 500 + 3)).message(),
                HasSubstr("fields[0] 'b': vertex 999 has value -inf"));
  }
}

}  // namespace
}  // namespace actopo::service
