#pragma once

// The loops of a factor list as a set of their keys, for comparing which loops
// a check kept or withdrew regardless of order.

#include <set>
#include <vector>

#include <dcl/backend/pcm.hpp>

namespace dcl::test {

inline std::set<backend::LoopId> loopIdsOf(const std::vector<backend::Factor>& loops) {
  std::set<backend::LoopId> ids;
  for (const backend::Factor& f : loops) ids.insert(backend::loopId(f));
  return ids;
}

}  // namespace dcl::test
