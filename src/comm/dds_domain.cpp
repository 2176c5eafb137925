// A process's DDS domains and participants (dds_domain.hpp).
#include <cstdlib>
#include <map>
#include <mutex>
#include <string_view>
#include <utility>

#include <dcl/comm/dds_domain.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>

namespace dcl::comm {

namespace {

/// Cyclone's own log lines, which it writes to stderr by default: kept
/// instead, so that a failed call names Cyclone's reason in our one error
/// line, and passed to our log at debug level.
class CycloneLog {
 public:
  /// Installs the sinks; call before the first DDS call.
  static CycloneLog& instance() {
    static CycloneLog log;
    return log;
  }

  /// What Cyclone logged since the last take, on one line.
  std::string take() {
    const std::lock_guard lock(mutex_);
    return std::exchange(lines_, {});
  }

 private:
  CycloneLog() {
    dds_set_log_sink(&CycloneLog::onLog, this);
    dds_set_trace_sink(&CycloneLog::onTrace, nullptr);
  }

  static void onLog(void* self, const dds_log_data_t* data) {
    auto& log = *static_cast<CycloneLog*>(self);
    std::string_view text(data->message, data->size);
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.remove_suffix(1);
    spdlog::debug("Cyclone DDS: {}", text);
    const std::lock_guard lock(log.mutex_);
    if (log.lines_.size() < kMaxKept)
      log.lines_.append(log.lines_.empty() ? "" : "; ").append(text);
  }
  static void onTrace(void*, const dds_log_data_t*) {}

  static constexpr std::size_t kMaxKept = 1000;
  std::mutex mutex_;
  std::string lines_;
};

/// Cyclone's configuration for one interface with multicast discovery on it
/// (multicast is off by default on loopback, and discovery needs it).
std::string interfaceXml(const std::string& interface, std::size_t max_sample_bytes) {
  return "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"" + interface +
         "\" multicast=\"true\"/></Interfaces><AllowMulticast>true</AllowMulticast></General>"
         "<Internal><MaxSampleSize>" +
         std::to_string(max_sample_bytes) + "B</MaxSampleSize></Internal></Domain></CycloneDDS>";
}

/// The DDS domains this process has joined. A domain created with an explicit
/// configuration lives until it is deleted, and deleting it deletes every
/// participant in it, so several transports of one process (tests, a swarm
/// in one process) share it and the last one to leave deletes it.
class DomainRegistry {
 public:
  static DomainRegistry& instance() {
    static DomainRegistry registry;
    return registry;
  }

  void acquire(std::uint32_t domain, const std::string& interface, std::size_t max_sample_bytes) {
    CycloneLog::instance().take();  // sinks in place, and nothing stale in them
    const std::lock_guard lock(mutex_);
    auto it = domains_.find(domain);
    if (it == domains_.end()) {
      dds_entity_t handle = 0;  // 0: created with the first participant, deleted with the last
      if (!interface.empty()) {
        // The user's configuration (CYCLONEDDS_URI) first, ours after it: a
        // domain made with a configuration of its own would ignore theirs.
        const char* user = std::getenv("CYCLONEDDS_URI");
        const std::string xml = (user != nullptr && *user != '\0' ? std::string(user) + "," : "") +
                                interfaceXml(interface, max_sample_bytes);
        handle = ddsChecked(dds_create_domain(domain, xml.c_str()),
                            "dds_create_domain(domain " + std::to_string(domain) + ", interface '" +
                                interface + "')");
      }
      it = domains_.emplace(domain, Entry{handle, interface, max_sample_bytes, 0}).first;
    } else if (!interface.empty() && interface != it->second.interface) {
      throw core::Error("dds config: field 'interface' is '" + interface + "' but domain " +
                        std::to_string(domain) + " is already open in this process with " +
                        (it->second.interface.empty() ? std::string("the default interfaces")
                                                      : "'" + it->second.interface + "'"));
    } else if (!it->second.interface.empty() && max_sample_bytes > it->second.max_sample_bytes) {
      throw core::Error("DDS domain " + std::to_string(domain) +
                        " is open in this process for samples of " +
                        std::to_string(it->second.max_sample_bytes) + " bytes at most, and " +
                        std::to_string(max_sample_bytes) + " are asked for: use another domain");
    }
    ++it->second.users;
  }

  void release(std::uint32_t domain) {
    const std::lock_guard lock(mutex_);
    const auto it = domains_.find(domain);
    if (it == domains_.end() || --it->second.users > 0) return;
    if (it->second.handle > 0) dds_delete(it->second.handle);
    domains_.erase(it);
  }

 private:
  struct Entry {
    dds_entity_t handle = 0;
    std::string interface;
    std::size_t max_sample_bytes = 0;
    int users = 0;
  };
  std::mutex mutex_;
  std::map<std::uint32_t, Entry> domains_;
};

}  // namespace

void ddsFail(const std::string& call, dds_return_t rc) {
  const std::string cyclone = CycloneLog::instance().take();
  throw core::Error("DDS: " + call + " failed: " + dds_strretcode(rc) +
                    (cyclone.empty() ? "" : " (Cyclone DDS: " + cyclone + ")"));
}

dds_entity_t ddsChecked(dds_entity_t entity, const std::string& call) {
  if (entity < 0) ddsFail(call, entity);
  return entity;
}

DdsDomainLease::DdsDomainLease(std::uint32_t domain, const std::string& interface,
                               std::size_t max_sample_bytes)
    : domain_(domain) {
  DomainRegistry::instance().acquire(domain, interface, max_sample_bytes);
}

DdsDomainLease::~DdsDomainLease() {
  DomainRegistry::instance().release(domain_);
}

DdsParticipant::DdsParticipant(std::uint32_t domain)
    : handle_(ddsChecked(dds_create_participant(domain, nullptr, nullptr),
                         "dds_create_participant(domain " + std::to_string(domain) + ")")) {}

DdsParticipant::~DdsParticipant() {
  dds_delete(handle_);
}

}  // namespace dcl::comm
