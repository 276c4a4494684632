#include "nats_client.h"

#include <nats/nats.h>

#include <algorithm>

#include "protocol/secure_io.h"

namespace pc::relay {

namespace {

std::int64_t millis(double seconds) {
  return std::max<std::int64_t>(1, std::int64_t(seconds * 1e3));
}

// "<what>: <libnats' status text> (<its last error, where it says more>)".
Error natsError(const std::string& what, natsStatus s) {
  std::string message = what + ": " + natsStatus_GetText(s);
  natsStatus last = NATS_OK;
  if (const char* detail = nats_GetLastError(&last);
      detail && *detail && message.find(detail) == std::string::npos)
    message += std::string(" (") + detail + ")";
  return Error{message};
}

struct FreeOptions {
  void operator()(natsOptions* o) const { natsOptions_Destroy(o); }
};
struct FreeEntry {
  void operator()(kvEntry* e) const { kvEntry_Destroy(e); }
};
struct FreeMsg {
  void operator()(natsMsg* m) const { natsMsg_Destroy(m); }
};

// The comma-separated URLs as libnats' server list.
std::vector<std::string> splitUrls(const std::string& urls) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= urls.size()) {
    const std::size_t comma = std::min(urls.find(',', start), urls.size());
    if (comma > start) out.push_back(urls.substr(start, comma - start));
    start = comma + 1;
  }
  return out;
}

}  // namespace

void KvWatcher::Free::operator()(__kvWatcher* w) const {
  kvWatcher_Stop(w);
  kvWatcher_Destroy(w);
}

Result<std::optional<KvChange>> KvWatcher::next(double timeoutSeconds) {
  if (!w_) return Error{"watch: no watcher"};
  kvEntry* raw = nullptr;
  const natsStatus s = kvWatcher_Next(&raw, w_.get(), millis(timeoutSeconds));
  if (s == NATS_TIMEOUT) return std::optional<KvChange>{};
  if (s != NATS_OK) return natsError("watch", s);
  KvChange change;
  if (!raw) {  // libnats' mark of the end of the initial values
    change.caughtUp = true;
    return std::optional<KvChange>{std::move(change)};
  }
  std::unique_ptr<kvEntry, FreeEntry> entry(raw);
  change.key = kvEntry_Key(raw);
  change.revision = kvEntry_Revision(raw);
  change.deleted = kvEntry_Operation(raw) != kvOp_Put;
  const auto* data = static_cast<const std::uint8_t*>(kvEntry_Value(raw));
  const int n = kvEntry_ValueLen(raw);
  if (data && n > 0) change.value.assign(data, data + n);
  return std::optional<KvChange>{std::move(change)};
}

void KvBucket::Free::operator()(__kvStore* kv) const { kvStore_Destroy(kv); }

Result<std::uint64_t> KvBucket::put(const std::string& key, std::span<const std::uint8_t> value) {
  if (!kv_) return Error{"put " + key + ": no bucket"};
  std::uint64_t revision = 0;
  const natsStatus s =
      kvStore_Put(&revision, kv_.get(), key.c_str(), value.data(), int(value.size()));
  if (s != NATS_OK)
    return natsError("put " + name_ + "/" + key + " (" + std::to_string(value.size()) + " bytes)",
                     s);
  return revision;
}

Result<std::optional<std::vector<std::uint8_t>>> KvBucket::get(const std::string& key) {
  if (!kv_) return Error{"get " + key + ": no bucket"};
  kvEntry* raw = nullptr;
  const natsStatus s = kvStore_Get(&raw, kv_.get(), key.c_str());
  if (s == NATS_NOT_FOUND) return std::optional<std::vector<std::uint8_t>>{};
  if (s != NATS_OK) return natsError("get " + name_ + "/" + key, s);
  std::unique_ptr<kvEntry, FreeEntry> entry(raw);
  const auto* data = static_cast<const std::uint8_t*>(kvEntry_Value(raw));
  std::vector<std::uint8_t> value;
  if (data) value.assign(data, data + kvEntry_ValueLen(raw));
  return std::optional<std::vector<std::uint8_t>>{std::move(value)};
}

Result<KvWatcher> KvBucket::watchAll() {
  if (!kv_) return Error{"watch: no bucket"};
  kvWatcher* w = nullptr;
  const natsStatus s = kvStore_WatchAll(&w, kv_.get(), nullptr);
  if (s != NATS_OK) return natsError("watch " + name_, s);
  return KvWatcher(w);
}

void NatsSubscription::Free::operator()(__natsSubscription* s) const {
  natsSubscription_Unsubscribe(s);
  natsSubscription_Destroy(s);
}

Result<std::optional<NatsMessage>> NatsSubscription::next(double timeoutSeconds) {
  if (!s_) return Error{"next message: no subscription"};
  natsMsg* raw = nullptr;
  const natsStatus s = natsSubscription_NextMsg(&raw, s_.get(), millis(timeoutSeconds));
  if (s == NATS_TIMEOUT) return std::optional<NatsMessage>{};
  if (s != NATS_OK) return natsError("next message", s);
  std::unique_ptr<natsMsg, FreeMsg> msg(raw);
  NatsMessage out;
  out.subject = natsMsg_GetSubject(raw);
  const auto* data = reinterpret_cast<const std::uint8_t*>(natsMsg_GetData(raw));
  if (data) out.data.assign(data, data + natsMsg_GetDataLength(raw));
  return std::optional<NatsMessage>{std::move(out)};
}

void NatsConnection::FreeConnection::operator()(__natsConnection* nc) const {
  natsConnection_Destroy(nc);
}
void NatsConnection::FreeJs::operator()(__jsCtx* js) const { jsCtx_Destroy(js); }

Result<NatsConnection> NatsConnection::connect(const NatsOptions& options) {
  const std::vector<std::string> urls = splitUrls(options.urls);
  if (urls.empty()) return Error{"NATS: no server URL given"};
  natsOptions* raw = nullptr;
  if (natsStatus s = natsOptions_Create(&raw); s != NATS_OK) return natsError("NATS options", s);
  std::unique_ptr<natsOptions, FreeOptions> opts(raw);
  std::vector<const char*> list;
  for (const std::string& u : urls) list.push_back(u.c_str());
  natsStatus s = natsOptions_SetServers(raw, list.data(), int(list.size()));
  if (s == NATS_OK && !options.name.empty()) s = natsOptions_SetName(raw, options.name.c_str());
  if (s == NATS_OK) s = natsOptions_SetTimeout(raw, millis(options.connectTimeout));
  // Reconnect forever: an edge process outlives any NATS server's restart.
  if (s == NATS_OK) s = natsOptions_SetAllowReconnect(raw, true);
  if (s == NATS_OK) s = natsOptions_SetMaxReconnect(raw, -1);
  if (s == NATS_OK) s = natsOptions_SetReconnectWait(raw, millis(options.reconnectWait));
  // A dead server is noticed within about two seconds, not the default two minutes.
  if (s == NATS_OK) s = natsOptions_SetPingInterval(raw, 1000);
  if (s == NATS_OK) s = natsOptions_SetMaxPingsOut(raw, 2);
  if (s != NATS_OK) return natsError("NATS options", s);
  if (!options.caFile.empty()) {
    s = natsOptions_SetSecure(raw, true);
    if (s == NATS_OK) s = natsOptions_LoadCATrustedCertificates(raw, options.caFile.c_str());
    if (s != NATS_OK) return natsError("NATS CA file " + options.caFile, s);
  }
  if (!options.passwordFile.empty()) {
    if (options.user.empty())
      return Error{"NATS password file " + options.passwordFile + ": no user"};
    auto text = readSmallFile(options.passwordFile, 4096);
    if (!text) return Error{"NATS password file: " + text.error().message};
    std::string password = text->substr(0, text->find_first_of("\r\n"));
    if (password.empty()) return Error{"NATS password file " + options.passwordFile + ": empty"};
    s = natsOptions_SetUserInfo(raw, options.user.c_str(), password.c_str());
    if (s != NATS_OK) return natsError("NATS user " + options.user, s);
  }
  if (!options.credentialsFile.empty()) {
    s = natsOptions_SetUserCredentialsFromFiles(raw, options.credentialsFile.c_str(), nullptr);
    if (s != NATS_OK) return natsError("NATS credentials " + options.credentialsFile, s);
  }
  natsConnection* nc = nullptr;
  s = natsConnection_Connect(&nc, raw);
  if (s != NATS_OK) return natsError("NATS connect to " + options.urls, s);
  NatsConnection c;
  c.nc_.reset(nc);
  jsOptions jsOpts;
  jsOptions_Init(&jsOpts);
  jsOpts.Wait = millis(options.requestTimeout);
  jsCtx* js = nullptr;
  s = natsConnection_JetStream(&js, nc, &jsOpts);
  if (s != NATS_OK) return natsError("JetStream context", s);
  c.js_.reset(js);
  return c;
}

Status NatsConnection::publish(const std::string& subject, std::span<const std::uint8_t> data) {
  if (!nc_) return Error{"publish " + subject + ": not connected"};
  const natsStatus s =
      natsConnection_Publish(nc_.get(), subject.c_str(), data.data(), int(data.size()));
  if (s != NATS_OK) return natsError("publish " + subject, s);
  return Status::success();
}

Result<NatsSubscription> NatsConnection::subscribe(const std::string& subject) {
  if (!nc_) return Error{"subscribe " + subject + ": not connected"};
  natsSubscription* sub = nullptr;
  const natsStatus s = natsConnection_SubscribeSync(&sub, nc_.get(), subject.c_str());
  if (s != NATS_OK) return natsError("subscribe " + subject, s);
  return NatsSubscription(sub);
}

Status NatsConnection::flush(double timeoutSeconds) {
  if (!nc_) return Error{"flush: not connected"};
  const natsStatus s = natsConnection_FlushTimeout(nc_.get(), millis(timeoutSeconds));
  if (s != NATS_OK) return natsError("flush", s);
  return Status::success();
}

bool NatsConnection::connected() const {
  return nc_ && natsConnection_Status(nc_.get()) == NATS_CONN_STATUS_CONNECTED;
}

std::int64_t NatsConnection::maxPayload() const {
  return nc_ ? natsConnection_GetMaxPayload(nc_.get()) : 0;
}

Result<KvBucket> NatsConnection::createBucket(const BucketOptions& options) {
  if (!js_) return Error{"bucket " + options.name + ": not connected"};
  kvConfig config;
  kvConfig_Init(&config);
  config.Bucket = options.name.c_str();
  config.History = std::uint8_t(std::clamp(options.history, 1, 64));
  config.MaxValueSize =
      options.maxValueBytes > 0 ? options.maxValueBytes : std::int32_t(maxPayload());
  config.StorageType = options.memoryStorage ? js_MemoryStorage : js_FileStorage;
  config.Replicas = std::max(1, options.replicas);
  kvStore* kv = nullptr;
  const natsStatus s = js_CreateKeyValue(&kv, js_.get(), &config);
  if (s != NATS_OK) return natsError("create bucket " + options.name, s);
  return KvBucket(kv, options.name);
}

Result<KvBucket> NatsConnection::openBucket(const std::string& name) {
  if (!js_) return Error{"bucket " + name + ": not connected"};
  kvStore* kv = nullptr;
  const natsStatus s = js_KeyValue(&kv, js_.get(), name.c_str());
  if (s != NATS_OK) return natsError("open bucket " + name, s);
  return KvBucket(kv, name);
}

}  // namespace pc::relay
