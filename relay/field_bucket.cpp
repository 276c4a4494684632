#include "field_bucket.h"

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>

namespace pc::relay {

namespace {

constexpr std::uint32_t kCatalogueMagic = 0x43464350;  // "PCFC"
constexpr std::uint32_t kStateMagic = 0x53464350;      // "PCFS"
constexpr std::uint32_t kBrickMagic = 0x42464350;      // "PCFB"
constexpr std::uint32_t kPosesMagic = 0x50464350;      // "PCFP"

// Little-endian fields, one after another.
class Writer {
 public:
  template <typename T>
  void put(T v) {
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    out.insert(out.end(), b, b + sizeof(T));
  }
  void bytes(std::span<const std::uint8_t> b) { out.insert(out.end(), b.begin(), b.end()); }
  void string(const std::string& s) {
    put(std::uint16_t(std::min<std::size_t>(s.size(), 0xFFFF)));
    out.insert(out.end(), s.begin(), s.begin() + std::min<std::size_t>(s.size(), 0xFFFF));
  }
  std::vector<std::uint8_t> out;
};

// Reads what Writer wrote; any read past the end sets `failed` and yields zeros.
class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> b) : in_(b) {}
  template <typename T>
  T get() {
    T v{};
    if (pos_ + sizeof(T) > in_.size()) {
      failed = true;
      return v;
    }
    std::memcpy(&v, in_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  std::string string() {
    const std::size_t n = get<std::uint16_t>();
    if (pos_ + n > in_.size()) return failed = true, std::string();
    std::string s(reinterpret_cast<const char*>(in_.data() + pos_), n);
    pos_ += n;
    return s;
  }
  std::vector<std::uint8_t> rest() {
    std::vector<std::uint8_t> v(in_.begin() + std::ptrdiff_t(std::min(pos_, in_.size())),
                                in_.end());
    pos_ = in_.size();
    return v;
  }
  // Checks the magic and the format version.
  Status header(std::uint32_t magic, const char* what) {
    if (get<std::uint32_t>() != magic || failed)
      return Error{std::string(what) + ": not a " + what + " record"};
    const std::uint16_t format = get<std::uint16_t>();
    if (format != kBucketFormat)
      return Error{std::string(what) + ": format " + std::to_string(format) +
                   ", this build reads " + std::to_string(kBucketFormat)};
    return Status::success();
  }
  bool failed = false;

 private:
  std::span<const std::uint8_t> in_;
  std::size_t pos_ = 0;
};

Writer header(std::uint32_t magic) {
  Writer w;
  w.put(magic);
  w.put(kBucketFormat);
  return w;
}

}  // namespace

std::string brickKey(int cascade, std::uint32_t brick) {
  return "brick." + std::to_string(cascade) + "." + std::to_string(brick);
}

std::optional<std::pair<int, std::uint32_t>> parseBrickKey(const std::string& key) {
  unsigned cascade = 0, brick = 0;
  int used = 0;
  if (std::sscanf(key.c_str(), "brick.%u.%u%n", &cascade, &brick, &used) != 2 ||
      std::size_t(used) != key.size() || cascade > 255)
    return std::nullopt;
  return std::make_pair(int(cascade), std::uint32_t(brick));
}

std::vector<std::uint8_t> encodeCatalogue(const CatalogueRecord& r) {
  Writer w = header(kCatalogueMagic);
  w.put(r.epoch);
  w.string(r.sceneName);
  w.bytes(r.sessionInfoFrame);
  return std::move(w.out);
}

Result<CatalogueRecord> decodeCatalogue(std::span<const std::uint8_t> bytes) {
  Reader r(bytes);
  if (Status s = r.header(kCatalogueMagic, "catalogue"); !s) return s.error();
  CatalogueRecord c;
  c.epoch = r.get<std::uint64_t>();
  c.sceneName = r.string();
  c.sessionInfoFrame = r.rest();
  if (r.failed || c.sessionInfoFrame.empty()) return Error{"catalogue: truncated"};
  return c;
}

std::vector<std::uint8_t> encodeState(const StateRecord& r) {
  Writer w = header(kStateMagic);
  w.put(r.epoch);
  w.put(r.fieldVersion);
  w.put(r.wallTime);
  w.bytes(r.sceneStateFrame);
  return std::move(w.out);
}

Result<StateRecord> decodeState(std::span<const std::uint8_t> bytes) {
  Reader r(bytes);
  if (Status s = r.header(kStateMagic, "state"); !s) return s.error();
  StateRecord st;
  st.epoch = r.get<std::uint64_t>();
  st.fieldVersion = r.get<std::uint64_t>();
  st.wallTime = r.get<double>();
  st.sceneStateFrame = r.rest();
  if (r.failed || st.sceneStateFrame.empty() || !std::isfinite(st.wallTime))
    return Error{"state: truncated or bad time"};
  return st;
}

std::vector<std::uint8_t> encodeBrickRecord(const BrickRecord& r) {
  Writer w = header(kBrickMagic);
  w.put(r.epoch);
  w.put(r.cascade);
  w.put(r.brick);
  w.put(r.version);
  w.put(r.wallTime);
  w.bytes(r.payload);
  return std::move(w.out);
}

Result<BrickRecord> decodeBrickRecord(std::span<const std::uint8_t> bytes) {
  Reader r(bytes);
  if (Status s = r.header(kBrickMagic, "brick"); !s) return s.error();
  BrickRecord b;
  b.epoch = r.get<std::uint64_t>();
  b.cascade = r.get<std::uint16_t>();
  b.brick = r.get<std::uint32_t>();
  b.version = r.get<std::uint64_t>();
  b.wallTime = r.get<double>();
  b.payload = r.rest();
  if (r.failed || b.payload.empty() || b.version == 0 || !std::isfinite(b.wallTime))
    return Error{"brick: truncated, version 0 or bad time"};
  return b;
}

std::string posesSubject(const std::string& bucket, const std::string& relay) {
  return "probecast." + bucket + ".poses." + relay;
}
std::string loadSubject(const std::string& bucket, const std::string& relay) {
  return "probecast." + bucket + ".load." + relay;
}
std::string posesWildcard(const std::string& bucket) { return "probecast." + bucket + ".poses.*"; }
std::string loadWildcard(const std::string& bucket) { return "probecast." + bucket + ".load.*"; }

std::vector<std::uint8_t> encodePoses(const PosesMessage& m) {
  Writer w = header(kPosesMagic);
  w.string(m.relay);
  const std::size_t n = std::min({m.positions.size(), m.weights.size(), kMaxPosesPerMessage});
  w.put(std::uint32_t(n));
  for (std::size_t i = 0; i < n; ++i) {
    w.put(m.positions[i].x);
    w.put(m.positions[i].y);
    w.put(m.positions[i].z);
    w.put(m.weights[i]);
  }
  return std::move(w.out);
}

Result<PosesMessage> decodePoses(std::span<const std::uint8_t> bytes) {
  Reader r(bytes);
  if (Status s = r.header(kPosesMagic, "poses"); !s) return s.error();
  PosesMessage m;
  m.relay = r.string();
  const std::uint32_t n = r.get<std::uint32_t>();
  if (r.failed || n > kMaxPosesPerMessage) return Error{"poses: truncated or over the count cap"};
  for (std::uint32_t i = 0; i < n; ++i) {
    glm::vec3 p;
    p.x = r.get<float>();
    p.y = r.get<float>();
    p.z = r.get<float>();
    const float weight = r.get<float>();
    if (r.failed) return Error{"poses: truncated"};
    // A position or weight that is not a finite number is left out, not trusted.
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) ||
        !std::isfinite(weight) || weight <= 0)
      continue;
    m.positions.push_back(p);
    m.weights.push_back(weight);
  }
  return m;
}

std::vector<std::uint8_t> encodeLoad(const LoadMessage& m) {
  const nlohmann::json j = {{"relay", m.relay},
                            {"endpoint", m.endpoint},
                            {"clients", m.clients},
                            {"max_clients", m.maxClients}};
  const std::string text = j.dump();
  return std::vector<std::uint8_t>(text.begin(), text.end());
}

Result<LoadMessage> decodeLoad(std::span<const std::uint8_t> bytes) {
  const auto j = nlohmann::json::parse(bytes.begin(), bytes.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object()) return Error{"load: not a JSON object"};
  LoadMessage m;
  const auto text = [&](const char* k) {
    return j.contains(k) && j[k].is_string() ? j[k].get<std::string>() : std::string();
  };
  const auto count = [&](const char* k) {
    return j.contains(k) && j[k].is_number_unsigned() ? j[k].get<std::uint64_t>()
                                                      : std::uint64_t(0);
  };
  m.relay = text("relay");
  m.endpoint = text("endpoint");
  m.clients = count("clients");
  m.maxClients = count("max_clients");
  if (m.relay.empty()) return Error{"load: no relay name"};
  return m;
}

bool validToken(const std::string& s) {
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s)
    if (!std::isalnum(c) && c != '-' && c != '_') return false;
  return true;
}

}  // namespace pc::relay
