// ROS 1 graph names (ros1_node.hpp).
#include <cctype>
#include <string_view>

#include <fmt/format.h>

#include <dcl/ros/ros1_node.hpp>

namespace dcl::ros1 {

void checkTopicName(const std::string& name) {
  std::string_view rest(name);
  if (!rest.empty() && rest.front() == '/') rest.remove_prefix(1);
  bool valid = !rest.empty() && name.size() <= 255;
  while (valid && !rest.empty()) {
    const std::string_view part = rest.substr(0, rest.find('/'));
    valid = !part.empty() && std::isalpha(static_cast<unsigned char>(part.front())) != 0;
    for (const char c : part)
      valid = valid && (std::isalnum(static_cast<unsigned char>(c)) || c == '_');
    rest.remove_prefix(std::min(rest.size(), part.size() + 1));
    if (valid && rest.empty() && name.back() == '/') valid = false;
  }
  if (!valid) {
    throw core::Error(fmt::format(
        "ROS 1 name '{}': a name is parts of letters, digits and '_' between '/', each starting "
        "with a letter",
        name));
  }
}

}  // namespace dcl::ros1
