#pragma once

/// Base64 (RFC 4648, with padding): bytes carried in text, as a page embeds a
/// picture and a JSON message its binary fields.

#include <cstdint>
#include <span>
#include <string>

namespace dcl::core {

std::string base64(std::span<const std::uint8_t> bytes);

}  // namespace dcl::core
