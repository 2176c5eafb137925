#include "bag_file.hpp"

#include <algorithm>
#include <cstring>
#include <new>
#include <optional>
#include <string_view>
#include <utility>

#include <bzlib.h>
#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>

#include "decompress.hpp"

namespace dcl::io::detail {

namespace {

using core::FileError;
using core::FileLocation;

constexpr std::string_view kMagic = "#ROSBAG V2.0\n";

// Record op codes of format 2.0.
constexpr std::uint8_t kOpMessageData = 0x02;
constexpr std::uint8_t kOpBagHeader = 0x03;
constexpr std::uint8_t kOpIndexData = 0x04;
constexpr std::uint8_t kOpChunk = 0x05;
constexpr std::uint8_t kOpChunkInfo = 0x06;
constexpr std::uint8_t kOpConnection = 0x07;

/// Ceilings on what the file claims, checked before anything is allocated.
/// Record headers hold a few short fields (connection definitions sit in the
/// data); rosbag's chunks are 768 KiB, and one holds at least one message.
constexpr std::uint32_t kMaxHeaderBytes = std::uint32_t{1} << 20;
constexpr std::uint32_t kMaxChunkBytes = std::uint32_t{1} << 30;
/// A compressed chunk may claim at most this many times its bytes (LZ4 reaches
/// 255 at most; bz2 on real sensor data a few): a few kilobytes of a hostile
/// bz2 stream must not unfold into a gigabyte.
constexpr std::uint64_t kMaxCompressionRatio = 1000;

/// The fields of a record header (or of a connection record's data):
/// a sequence of uint32 length + "name=value".
class Fields {
 public:
  /// Parses `bytes`; `fail` receives what is wrong.
  template <class Fail>
  Fields(std::span<const char> bytes, Fail&& fail) {
    std::size_t at = 0;
    while (at < bytes.size()) {
      if (bytes.size() - at < 4) fail(fmt::format("header field length cut at byte {}", at));
      std::uint32_t length = 0;
      std::memcpy(&length, bytes.data() + at, 4);
      at += 4;
      if (length > bytes.size() - at) {
        fail(fmt::format("header field of {} bytes overruns the header ({} bytes left)", length,
                         bytes.size() - at));
      }
      const std::string_view field(bytes.data() + at, length);
      at += length;
      const std::size_t equals = field.find('=');
      if (equals == std::string_view::npos) {
        fail(fmt::format("header field without '=' at byte {}", at - length));
      }
      fields_.emplace_back(field.substr(0, equals), field.substr(equals + 1));
    }
  }

  [[nodiscard]] std::optional<std::string_view> find(std::string_view name) const {
    for (const auto& [n, value] : fields_) {
      if (n == name) return value;
    }
    return std::nullopt;
  }

  /// The field `name` as a little-endian T; none when absent or of another size.
  template <class T>
  [[nodiscard]] std::optional<T> number(std::string_view name) const {
    const auto value = find(name);
    if (!value || value->size() != sizeof(T)) return std::nullopt;
    T out{};
    std::memcpy(&out, value->data(), sizeof(T));
    return out;
  }

 private:
  std::vector<std::pair<std::string_view, std::string_view>> fields_;
};

/// One record's header and where its data lies, in a file or in a chunk's content.
struct Record {
  std::uint8_t op = 0;
  std::uint64_t data_at = 0;
  std::uint32_t data_size = 0;
};

std::string printable(std::string_view text) {
  std::string out;
  for (const char c : text.substr(0, 64)) {
    out += (c >= 0x20 && c < 0x7f) ? c : '?';
  }
  return out;
}

/// The connection id and the record time (ns) of a message data record.
template <class Fail>
std::pair<std::uint32_t, std::uint64_t> messageKey(const Fields& fields, Fail&& fail) {
  const auto id = fields.number<std::uint32_t>("conn");
  const auto time = fields.number<std::uint64_t>("time");  // uint32 sec, then uint32 nsec
  if (!id || !time) fail("message header lacks a 4-byte 'conn' or an 8-byte 'time'");
  return {*id, (*time & 0xffffffffU) * 1'000'000'000ULL + (*time >> 32)};
}

template <class Fail>
void decompressBz2(std::span<const char> in, std::uint32_t size, std::vector<char>& out,
                   void* (*allocate)(void*, int, int), void (*release)(void*, void*), void* memory,
                   Fail&& fail) {
  bz_stream stream{};
  stream.bzalloc = allocate;
  stream.bzfree = release;
  stream.opaque = memory;
  if (BZ2_bzDecompressInit(&stream, 0, 0) != BZ_OK) fail("cannot start bz2 decompression");
  struct End {
    bz_stream* s;
    ~End() { BZ2_bzDecompressEnd(s); }
  } end{&stream};
  const auto step = [&](std::span<const char> input, std::span<char> room) {
    stream.next_in = const_cast<char*>(input.data());  // bzlib's API is not const-correct
    stream.avail_in = static_cast<unsigned>(input.size());
    stream.next_out = room.data();
    stream.avail_out = static_cast<unsigned>(room.size());
    const int rc = BZ2_bzDecompress(&stream);
    if (rc != BZ_OK && rc != BZ_STREAM_END) {
      fail(fmt::format("bz2 content is corrupt (bzlib error {})", rc));
    }
    return Step{input.size() - stream.avail_in, room.size() - stream.avail_out,
                rc == BZ_STREAM_END};
  };
  decompress(in, size, out, step, fail);
}

}  // namespace

BagFile::BagFile(std::string path) : path_(std::move(path)) {
  requireFile(path_);
  file_.open(path_, std::ios::binary);
  if (!file_) throw FileError({path_}, std::string("cannot open: ") + std::strerror(errno));
  file_.seekg(0, std::ios::end);
  file_size_ = static_cast<std::uint64_t>(file_.tellg());
  file_.seekg(0);
  file_at_ = 0;
  scan();
}

void BagFile::readAt(std::uint64_t byte, std::size_t n, std::vector<char>& out) {
  out.resize(n);
  if (byte != file_at_) {  // a seek drops the stream's buffer: only when needed
    file_.clear();
    file_.seekg(static_cast<std::streamoff>(byte));
  }
  if (n > 0 && !file_.read(out.data(), static_cast<std::streamsize>(n))) {
    file_at_ = kUnknownPosition;
    failAtByte(path_, byte, fmt::format("cannot read {} bytes: {}", n, std::strerror(errno)));
  }
  file_at_ = byte + n;
}

void BagFile::scan() {
  std::vector<char> bytes;
  readAt(0, std::min<std::uint64_t>(file_size_, kMagic.size()), bytes);
  const std::string_view start(bytes.data(), bytes.size());
  if (start != kMagic) {
    if (start.starts_with("#ROSBAG V")) {
      failAtByte(path_, 0,
                 fmt::format("bag format '{}' is not read, only 2.0 (ROS Groovy and later)",
                             printable(start.substr(9, start.find('\n') - 9))));
    }
    failAtByte(path_, 0, "not a ROS1 bag: it does not begin with '#ROSBAG V2.0'");
  }
  bool header_seen = false;
  std::uint64_t at = kMagic.size();
  std::vector<char> header;
  while (at < file_size_) {
    const std::uint64_t record_at = at;
    const auto fail = [&](const std::string& what) { failAtByte(path_, record_at, what); };
    const auto truncated = [&](std::uint64_t needed) {
      fail(fmt::format(
          "truncated: the file ends inside a record ({} bytes short); the recording may have "
          "been interrupted (`rosbag reindex` recovers the whole chunks of such a bag)",
          needed));
    };
    const auto readLength = [&](std::uint64_t where) {
      if (file_size_ - where < 4) truncated(4 - (file_size_ - where));
      std::uint32_t n = 0;
      readAt(where, 4, bytes);
      std::memcpy(&n, bytes.data(), 4);
      return n;
    };
    const std::uint32_t header_size = readLength(at);
    if (header_size > kMaxHeaderBytes) {
      fail(fmt::format("record header of {} bytes: corrupt (headers are at most {})", header_size,
                       kMaxHeaderBytes));
    }
    if (header_size > file_size_ - at - 4) truncated(header_size - (file_size_ - at - 4));
    readAt(at + 4, header_size, header);
    const Fields fields(header, [&](const std::string& what) { fail("record header: " + what); });
    const std::uint64_t size_at = at + 4 + header_size;
    const std::uint32_t data_size = readLength(size_at);
    const std::uint64_t data_at = size_at + 4;
    if (data_size > file_size_ - data_at) truncated(data_size - (file_size_ - data_at));
    const auto op = fields.number<std::uint8_t>("op");
    if (!op) fail("record header has no one-byte 'op' field");
    if (!header_seen && *op != kOpBagHeader) fail("the first record is not the bag header");
    switch (*op) {
      case kOpBagHeader: {
        if (header_seen) fail("a second bag header");
        header_seen = true;
        const auto index_at = fields.number<std::uint64_t>("index_pos");
        if (!index_at) fail("bag header has no 8-byte 'index_pos' field");
        if (*index_at > file_size_) {
          fail(fmt::format("truncated: the bag's index starts at byte {}, the file has {} bytes",
                           *index_at, file_size_));
        }
        if (const auto e = fields.find("encryptor"); e && !e->empty()) {
          fail(fmt::format("the bag is encrypted ({}): decrypt it first", printable(*e)));
        }
        break;
      }
      case kOpChunk: {
        const auto compression = fields.find("compression");
        const auto size = fields.number<std::uint32_t>("size");
        if (!compression || !size) fail("chunk header lacks 'compression' or a 4-byte 'size'");
        if (*compression != "none" && *compression != "bz2" && *compression != "lz4") {
          fail(fmt::format("chunk compression '{}' is unknown (none, bz2 or lz4)",
                           printable(*compression)));
        }
        if (*size > kMaxChunkBytes) {
          fail(fmt::format("chunk of {} bytes: corrupt (at most {})", *size, kMaxChunkBytes));
        }
        if (*compression != "none" && *size > kMaxCompressionRatio * data_size) {
          fail(fmt::format("chunk says {} bytes from {} compressed: corrupt (at most {} times)",
                           *size, data_size, kMaxCompressionRatio));
        }
        if (*compression == "none" && *size != data_size) {
          fail(fmt::format("uncompressed chunk says {} bytes and holds {}", *size, data_size));
        }
        chunks_.push_back({data_at, data_size, *size, std::string(*compression), record_at});
        scanChunk(chunks_.size() - 1);
        break;
      }
      case kOpConnection: {
        const auto id = fields.number<std::uint32_t>("conn");
        const auto topic = fields.find("topic");
        if (!id || !topic) fail("connection header lacks a 4-byte 'conn' or a 'topic'");
        std::vector<char> data;
        readAt(data_at, data_size, data);
        addConnection(*id, std::string(*topic), data, record_at);
        break;
      }
      case kOpMessageData: {
        const auto [id, time] = messageKey(fields, fail);
        messages_.push_back({0, time, BagMessage::kNoChunk, data_at, data_size, record_at});
        message_connection_ids_.push_back(id);
        break;
      }
      case kOpIndexData:
      case kOpChunkInfo:
        break;  // the index: not needed, the records themselves were read
      default:
        fail(fmt::format("unknown record op {:#04x}", *op));
    }
    at = data_at + data_size;
  }
  if (!header_seen) failAtByte(path_, at, "the bag holds no records (not even its header)");
  for (std::size_t i = 0; i < messages_.size(); ++i) {
    const auto found = connection_index_.find(message_connection_ids_[i]);
    if (found == connection_index_.end()) {
      failAtByte(path_, messages_[i].record_byte,
                 fmt::format("a message on connection {}, which the bag never defines",
                             message_connection_ids_[i]));
    }
    messages_[i].connection = found->second;
  }
  message_connection_ids_ = {};
}

void BagFile::scanChunk(std::size_t index) {
  loadChunk(index);
  const Chunk& chunk = chunks_[index];
  const std::span<const char> content(chunk_bytes_);
  std::size_t at = 0;
  while (at < content.size()) {
    const std::size_t record_at = at;
    const auto fail = [&](const std::string& what) {
      failAtByte(path_, chunk.record_byte,
                 fmt::format("chunk ({}): at byte {} of its content: {}", chunk.compression,
                             record_at, what));
    };
    const auto readLength = [&](std::size_t where) {
      if (content.size() - where < 4) fail("a record is cut off by the end of the chunk");
      std::uint32_t n = 0;
      std::memcpy(&n, content.data() + where, 4);
      return n;
    };
    const std::uint32_t header_size = readLength(at);
    if (header_size > content.size() - at - 4) fail("a record header overruns the chunk");
    const Fields fields(content.subspan(at + 4, header_size),
                        [&](const std::string& what) { fail("record header: " + what); });
    const std::size_t size_at = at + 4 + header_size;
    const std::uint32_t data_size = readLength(size_at);
    const std::size_t data_at = size_at + 4;
    if (data_size > content.size() - data_at) fail("a record's data overruns the chunk");
    const auto op = fields.number<std::uint8_t>("op");
    if (!op) fail("record header has no one-byte 'op' field");
    const auto id = fields.number<std::uint32_t>("conn");
    if (*op == kOpConnection) {
      const auto topic = fields.find("topic");
      if (!id || !topic) fail("connection header lacks a 4-byte 'conn' or a 'topic'");
      addConnection(*id, std::string(*topic), content.subspan(data_at, data_size),
                    chunk.record_byte);
    } else if (*op == kOpMessageData) {
      const auto [message_id, time] = messageKey(fields, fail);
      messages_.push_back({0, time, index, data_at, data_size, chunk.record_byte});
      message_connection_ids_.push_back(message_id);
    } else {
      fail(fmt::format("record op {:#04x} inside a chunk (only connections and messages)", *op));
    }
    at = data_at + data_size;
  }
}

void BagFile::addConnection(std::uint32_t id, const std::string& topic, std::span<const char> data,
                            std::uint64_t byte) {
  const auto fail = [&](const std::string& what) {
    failAtByte(path_, byte, fmt::format("connection {} ('{}'): {}", id, printable(topic), what));
  };
  const Fields fields(data, fail);
  const auto type = fields.find("type");
  const auto md5sum = fields.find("md5sum");
  if (!type || !md5sum) fail("no 'type' or 'md5sum'");
  if (const auto known = connection_index_.find(id); known != connection_index_.end()) {
    const BagConnection& c = connections_[known->second];
    if (c.topic != topic || c.type != *type) {
      fail(fmt::format("defined again with another topic or type ('{}', {})", c.topic, c.type));
    }
    return;
  }
  connection_index_.emplace(id, connections_.size());
  connections_.push_back({id, topic, std::string(*type), std::string(*md5sum)});
}

void BagFile::loadChunk(std::size_t index) {
  if (loaded_chunk_ == index) return;
  loaded_chunk_ = BagMessage::kNoChunk;
  const Chunk& chunk = chunks_[index];
  const auto fail = [&](const std::string& what) {
    failAtByte(path_, chunk.record_byte, fmt::format("chunk ({}): {}", chunk.compression, what));
  };
  if (chunk.compression == "none") {
    readAt(chunk.data_byte, chunk.data_size, chunk_bytes_);
  } else {
    std::vector<char> compressed;
    readAt(chunk.data_byte, chunk.data_size, compressed);
    if (chunk.compression == "bz2") {
      decompressBz2(compressed, chunk.size, chunk_bytes_, &Bz2Memory::allocate, &Bz2Memory::release,
                    &bz2_memory_, fail);
    } else {
      decompressLz4(compressed, chunk.size, chunk_bytes_, fail);
    }
  }
  loaded_chunk_ = index;
}

void* BagFile::Bz2Memory::allocate(void* self, int count, int size) {
  auto& blocks = static_cast<Bz2Memory*>(self)->blocks_;
  if (count < 0 || size < 0) return nullptr;
  const std::size_t bytes = static_cast<std::size_t>(count) * static_cast<std::size_t>(size);
  for (Block& block : blocks) {
    if (!block.in_use && block.size == bytes) {
      block.in_use = true;
      return block.bytes.get();
    }
  }
  // bzlib holds three blocks at most at once (its state, and its block arrays).
  constexpr std::size_t kMaxKept = 8;
  if (blocks.size() == kMaxKept) {
    const auto idle =
        std::find_if(blocks.begin(), blocks.end(), [](const Block& b) { return !b.in_use; });
    if (idle == blocks.end()) return nullptr;
    blocks.erase(idle);
  }
  std::unique_ptr<char[]> fresh(new (std::nothrow) char[bytes == 0 ? 1 : bytes]);
  if (!fresh) return nullptr;
  blocks.push_back({std::move(fresh), bytes, true});
  return blocks.back().bytes.get();
}

void BagFile::Bz2Memory::release(void* self, void* block) {
  for (Block& b : static_cast<Bz2Memory*>(self)->blocks_) {
    if (b.bytes.get() == block) b.in_use = false;
  }
}

std::vector<BagMessage> BagFile::messages(
    const std::function<bool(const BagConnection&)>& keep) const {
  std::vector<BagMessage> out;
  for (const BagMessage& m : messages_) {
    if (keep(connections_[m.connection])) out.push_back(m);
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const BagMessage& a, const BagMessage& b) { return a.time < b.time; });
  return out;
}

std::span<const char> BagFile::read(const BagMessage& message) {
  if (message.chunk == BagMessage::kNoChunk) {
    readAt(message.offset, message.size, message_bytes_);
    return message_bytes_;
  }
  loadChunk(message.chunk);
  if (message.offset + message.size > chunk_bytes_.size()) {
    failAtByte(path_, message.record_byte, "the bag changed while it was read");
  }
  return std::span<const char>(chunk_bytes_).subspan(message.offset, message.size);
}

}  // namespace dcl::io::detail
