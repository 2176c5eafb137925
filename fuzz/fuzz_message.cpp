// libFuzzer target: comm::decode, the first thing every received datagram meets.
// Properties beyond "no crash, no exception": whatever decodes holds values the
// schema allows, so it encodes again, and that encoding decodes to the same kind.
#include <cstdint>
#include <cstdlib>
#include <span>

#include <dcl/comm/messages.hpp>
#include <dcl/core/error.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const dcl::comm::Decoded decoded = dcl::comm::decode(std::span(data, size));
  if (!decoded.message) {
    if (decoded.detail.empty()) std::abort();  // every drop names its reason
    return 0;
  }
  try {
    const dcl::comm::Decoded again = dcl::comm::decode(dcl::comm::encode(*decoded.message));
    if (!again.message || again.message->kind() != decoded.message->kind()) std::abort();
  } catch (const dcl::core::Error&) {
    std::abort();  // decoded, yet not encodable: the decoder let a bad value through
  }
  return 0;
}
