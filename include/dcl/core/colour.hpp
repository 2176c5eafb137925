#pragma once

/// One colour per robot in every picture the project draws: the report's
/// plots, the merged map (map.ply and the report's picture of it), the
/// simulator's world preview and the RViz snapshot.

#include <array>
#include <cstddef>
#include <cstdint>

namespace dcl::core {

/// Robot `index`'s colour (red, green, blue): ten distinct colours, none
/// pure green, red or grey (the report keeps those for accepted and
/// rejected loops and the ground truth), then hues a golden angle apart.
std::array<std::uint8_t, 3> robotColour(std::size_t index);

}  // namespace dcl::core
