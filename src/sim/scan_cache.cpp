#include "scan_cache.hpp"

#include <algorithm>
#include <string_view>
#include <system_error>
#include <utility>

#include <embree3/rtcore_config.h>
#include <fmt/format.h>
#include <gnu/libc-version.h>
#include <spdlog/spdlog.h>

#include <dcl/core/error.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pcd.hpp>

namespace dcl::sim::detail {
namespace {

namespace fs = std::filesystem;

/// 64-bit FNV-1a, continued over `bytes`.
std::uint64_t fnv1a(std::uint64_t hash, const void* bytes, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(bytes);
  for (std::size_t i = 0; i < size; ++i) hash = (hash ^ p[i]) * 0x100000001b3ULL;
  return hash;
}

std::uint64_t fnv1a(std::uint64_t hash, std::string_view text) {
  return fnv1a(hash, text.data(), text.size());
}

constexpr std::uint64_t kFnvBasis = 0xcbf29ce484222325ULL;

/// The running program's bytes, hashed once per process.
std::uint64_t programKey() {
  static const std::uint64_t key = [] {
    const std::vector<char> bytes = io::readFile("/proc/self/exe");
    return fnv1a(kFnvBasis, bytes.data(), bytes.size());
  }();
  return key;
}

}  // namespace

std::uint64_t simulationKey(const io::DatasetSpec& spec,
                            const std::vector<core::Trajectory>& ground_truth) {
  std::uint64_t hash = programKey();
  hash = fnv1a(hash, fmt::format("embree {}.{}.{} glibc {}", RTC_VERSION_MAJOR, RTC_VERSION_MINOR,
                                 RTC_VERSION_PATCH, gnu_get_libc_version()));
  io::DatasetSpec content = spec;
  content.folder.clear();  // the same dataset copied elsewhere has the same scans
  hash = fnv1a(hash, io::datasetYaml(content));
  for (const core::Trajectory& t : ground_truth) {
    hash = fnv1a(hash, t.stamps().data(), t.stamps().size() * sizeof(double));
    for (const Eigen::Isometry3d& pose : t.poses())
      hash = fnv1a(hash, pose.matrix().data(), 16 * sizeof(double));
  }
  return hash;
}

ScanCache::ScanCache(fs::path folder, std::uint64_t key, std::uint64_t max_bytes)
    : root_(std::move(folder)),
      dataset_folder_(root_ / fmt::format("{:016x}", key)),
      max_bytes_(max_bytes),
      stored_bytes_(max_bytes) {}  // the first store measures the folder

fs::path ScanCache::file(std::size_t robot, std::size_t index) const {
  return dataset_folder_ / fmt::format("{}-{:06}.pcd", robot, index);
}

std::optional<core::PointCloud> ScanCache::load(std::size_t robot, std::size_t index) const {
  const fs::path path = file(robot, index);
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  try {
    core::PointCloud scan = io::readPcd(path.string());
    // Read now: the last to go when the folder is trimmed.
    fs::last_write_time(path, fs::file_time_type::clock::now(), ec);
    ++hits_;
    return scan;
  } catch (const core::Error&) {
    return std::nullopt;  // damaged (a disk that filled, an edit): cast again
  }
}

void ScanCache::store(std::size_t robot, std::size_t index, const core::PointCloud& scan) {
  const fs::path path = file(robot, index);
  std::error_code ec;
  try {
    fs::create_directories(dataset_folder_);
    io::writePcd(path.string(), scan, {.encoding = io::PcdEncoding::kBinaryCompressed});
  } catch (const std::exception& e) {
    if (!warned_.exchange(true))
      spdlog::warn("scan cache {}: cannot keep scans there, casting without it: {}", root_.string(),
                   e.what());
    return;
  }
  ++stores_;
  const auto size = fs::file_size(path, ec);
  if (ec) return;
  const std::lock_guard lock(trim_mutex_);
  stored_bytes_ += size;
  // Measured again after an eighth of the bound was written: other
  // processes' files count too, and no process writes more unmeasured.
  if (stored_bytes_ >= max_bytes_ / 8) trim();
}

namespace {

/// True for a folder of the cache: a dataset key in 16 hexadecimal digits.
bool isDatasetFolder(const fs::path& path) {
  const std::string name = path.filename().string();
  return name.size() == 16 && name.find_first_not_of("0123456789abcdef") == std::string::npos;
}

/// True for a file the cache wrote: a scan (ROBOT-INDEX.pcd), or one left
/// half written under its temporary name (.ROBOT-INDEX.pcd.XXXXXX) by a
/// process that was killed. Nothing else in the folder is ever removed.
bool isCacheFile(const fs::path& path) {
  std::string name = path.filename().string();
  if (!name.empty() && name[0] == '.') {
    const auto end = name.find(".pcd.");
    if (end == std::string::npos) return false;
    name = name.substr(1, end + 3);
  }
  const auto dash = name.find('-');
  return name.size() > 4 && name.ends_with(".pcd") && dash != std::string::npos && dash > 0 &&
         name.find_first_not_of("0123456789", 0) == dash &&
         name.find_first_not_of("0123456789", dash + 1) == name.size() - 4;
}

}  // namespace

void ScanCache::trim() {
  stored_bytes_ = 0;
  struct Entry {
    fs::file_time_type time;
    std::uint64_t size;
    fs::path path;
  };
  std::vector<Entry> entries;
  std::uint64_t total = 0;
  std::error_code ec;
  for (auto dataset = fs::directory_iterator(root_, ec); !ec && dataset != fs::directory_iterator();
       dataset.increment(ec)) {
    if (!dataset->is_directory(ec) || !isDatasetFolder(dataset->path())) continue;
    std::error_code inner;
    for (auto it = fs::directory_iterator(dataset->path(), inner);
         !inner && it != fs::directory_iterator(); it.increment(inner)) {
      std::error_code entry;
      if (!it->is_regular_file(entry) || !isCacheFile(it->path())) continue;
      const auto size = it->file_size(entry);
      const auto time = it->last_write_time(entry);
      if (entry) continue;
      entries.push_back({time, size, it->path()});
      total += size;
    }
  }
  if (total <= max_bytes_) return;
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.time < b.time; });
  for (const Entry& e : entries) {
    if (total <= max_bytes_ / 4 * 3) break;
    if (fs::remove(e.path, ec)) total -= e.size;
  }
}

}  // namespace dcl::sim::detail
