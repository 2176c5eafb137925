#pragma once

// Bounded decompression of the compressed chunks of ROS1 bags and MCAP files:
// the output grows as the stream produces it, so that a false size in a
// damaged file costs no more memory than the real content, and the content
// must come to exactly the size the file claims. Private to dcl::io.

#include <algorithm>
#include <cstddef>
#include <span>
#include <vector>

#include <fmt/format.h>
#include <lz4frame.h>
#include <zstd.h>

namespace dcl::io::detail {

/// What one call of a streaming decompressor did.
struct Step {
  std::size_t consumed = 0;
  std::size_t produced = 0;
  bool done = false;  ///< the stream ended
};

/// Runs `step(input left, output room)` until the stream `in` ends, growing the
/// output as it comes; the content must come to exactly `size` bytes. `fail`
/// receives what is wrong (and must throw).
template <class StepFn, class Fail>
void decompress(std::span<const char> in, std::size_t size, std::vector<char>& out, StepFn&& step,
                Fail&& fail) {
  const std::size_t limit = size + 1;  // one byte more shows an overrun
  out.resize(std::min<std::size_t>(limit, std::size_t{1} << 16));
  std::size_t produced = 0, consumed = 0;
  for (;;) {
    const Step s = step(in.subspan(consumed), std::span<char>(out).subspan(produced));
    consumed += s.consumed;
    produced += s.produced;
    if (s.done) break;
    if (produced == out.size()) {
      if (out.size() == limit) break;
      out.resize(std::min(limit, 2 * out.size()));
    } else if (consumed == in.size() || (s.consumed == 0 && s.produced == 0)) {
      fail("compressed content ends before its stream does");
    }
  }
  if (produced != size) {
    fail(fmt::format("decompresses to {}{} bytes, its header says {}",
                     produced > size ? "more than " : "", std::min<std::size_t>(produced, size),
                     size));
  }
  out.resize(size);
}

/// An LZ4 frame (rosbag's roslz4 and MCAP's "lz4" chunks).
template <class Fail>
void decompressLz4(std::span<const char> in, std::size_t size, std::vector<char>& out,
                   Fail&& fail) {
  LZ4F_dctx* context = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&context, LZ4F_VERSION))) {
    fail("cannot start lz4 decompression");
  }
  struct Free {
    LZ4F_dctx* c;
    ~Free() { LZ4F_freeDecompressionContext(c); }
  } free{context};
  const auto step = [&](std::span<const char> input, std::span<char> room) {
    std::size_t in_size = input.size(), out_size = room.size();
    const std::size_t hint =
        LZ4F_decompress(context, room.data(), &out_size, input.data(), &in_size, nullptr);
    if (LZ4F_isError(hint)) {
      fail(fmt::format("lz4 content is corrupt ({})", LZ4F_getErrorName(hint)));
    }
    return Step{in_size, out_size, hint == 0};
  };
  decompress(in, size, out, step, fail);
}

/// A Zstandard frame (MCAP's "zstd" chunks).
template <class Fail>
void decompressZstd(std::span<const char> in, std::size_t size, std::vector<char>& out,
                    Fail&& fail) {
  ZSTD_DStream* stream = ZSTD_createDStream();
  if (stream == nullptr) fail("cannot start zstd decompression");
  struct Free {
    ZSTD_DStream* s;
    ~Free() { ZSTD_freeDStream(s); }
  } free{stream};
  // A frame may ask for a window of up to 2^31 bytes; MCAP chunks need no more than 2^27.
  ZSTD_DCtx_setParameter(stream, ZSTD_d_windowLogMax, 27);
  const auto step = [&](std::span<const char> input, std::span<char> room) {
    ZSTD_inBuffer from{input.data(), input.size(), 0};
    ZSTD_outBuffer to{room.data(), room.size(), 0};
    const std::size_t hint = ZSTD_decompressStream(stream, &to, &from);
    if (ZSTD_isError(hint)) {
      fail(fmt::format("zstd content is corrupt ({})", ZSTD_getErrorName(hint)));
    }
    return Step{from.pos, to.pos, hint == 0};
  };
  decompress(in, size, out, step, fail);
}

}  // namespace dcl::io::detail
