#pragma once

// For the fuzz targets of readers that take a path: each input is written to a
// file of this process, in memory (/dev/shm) where there is one, else in the
// temporary folder (a disk there made fuzzing ten times slower), removed when
// the fuzzer ends.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>

#include <sys/mman.h>
#include <unistd.h>

namespace dcl::fuzz {

/// Where the input files go: memory when the system offers a tmpfs.
inline std::filesystem::path scratchFolder() {
  std::error_code ec;
  if (std::filesystem::is_directory("/dev/shm", ec)) return "/dev/shm";
  return std::filesystem::temp_directory_path();
}

/// The file of one target in this process, holding the input being tried.
class InputFile {
 public:
  /// A file named after `target` and this process.
  explicit InputFile(const std::string& target)
      : path_((scratchFolder() / ("dcl_fuzz_" + target + "_" + std::to_string(::getpid())))
                  .string()) {}
  ~InputFile() {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;

  /// Writes the input as the whole file and returns its path.
  [[nodiscard]] const std::string& write(const std::uint8_t* data, std::size_t size) const {
    std::ofstream(path_, std::ios::binary | std::ios::trunc)
        .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    return path_;
  }

 private:
  std::string path_;
};

/// Hands the input to `read` as an anonymous in-memory file (a memfd, read
/// through /proc/self/fd/N), for readers that open a path: no file system is
/// touched. Does nothing if the memfd cannot be made or filled.
template <class Read>
void withMemoryFile(const char* name, const std::uint8_t* data, std::size_t size, Read read) {
  const int fd = ::memfd_create(name, 0);
  if (fd < 0) return;
  std::size_t written = 0;
  while (written < size) {
    const ssize_t n = ::write(fd, data + written, size - written);
    if (n <= 0) break;
    written += static_cast<std::size_t>(n);
  }
  if (written == size) read("/proc/self/fd/" + std::to_string(fd));
  ::close(fd);
}

}  // namespace dcl::fuzz
