// libFuzzer target: what a Foxglove client sends the live view (--viz), one
// text message of the Foxglove WebSocket protocol. Text may be refused only
// with core::Error; what is accepted stays within the protocol's bounds.
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include <dcl/core/error.hpp>
#include <dcl/viz/foxglove.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const dcl::viz::ClientRequest request = dcl::viz::parseClientMessage(text);
    if (request.subscribe.size() > dcl::viz::kMaxSubscriptions ||
        request.unsubscribe.size() > dcl::viz::kMaxSubscriptions)
      std::abort();
  } catch (const dcl::core::Error&) {
  }
  return 0;
}
