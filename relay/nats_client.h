// RAII over libnats (the NATS C client): a connection, its JetStream context, a key-value
// bucket, a watcher of the bucket's keys and a subscription to a subject. Every call that can
// fail returns a Result or Status naming the call, the bucket or subject, and libnats' own
// words. libnats runs its own threads (reading, pinging, reconnecting); a connection
// reconnects by itself for as long as it lives, and what is published while it is away is
// buffered up to a bound, then refused with an error.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/result.h"

// libnats' opaque types; nats/nats.h stays in the .cpp.
struct __natsConnection;
struct __jsCtx;
struct __kvStore;
struct __kvWatcher;
struct __natsSubscription;

namespace pc::relay {

struct NatsOptions {
  // One or more server URLs, comma-separated: nats://host:4222, tls://host:4222.
  std::string urls = "nats://127.0.0.1:4222";
  std::string name;             // the connection's name, shown by the NATS server's monitoring
  std::string credentialsFile;  // a .creds file (user JWT and nkey seed), else none
  // Or a user and the file holding its password (its first line): never on the command line,
  // where `ps` shows it.
  std::string user, passwordFile;
  std::string caFile;           // trust these CAs for tls:// servers (else the system's)
  double connectTimeout = 2.0;  // s per server and attempt
  // Every attempt after the connection was lost waits this long (libnats retries forever).
  double reconnectWait = 0.25;
  // How long a JetStream request (a put, a watch, a bucket) waits for its answer: after a
  // cluster node is lost, requests in flight time out and are made again against the others.
  double requestTimeout = 2.0;
};

// A key-value bucket's settings where it is created (an existing bucket keeps its own).
struct BucketOptions {
  std::string name = "probecast-field";
  int history = 1;                 // values kept per key: 1, the current one, is all relays need
  std::int32_t maxValueBytes = 0;  // the largest value (0: the server's max payload)
  bool memoryStorage = false;      // memory instead of files (gone when the NATS server restarts)
  int replicas = 1;                // copies across a JetStream cluster's nodes
};

// One change of a watched bucket: a key's new value (or its deletion), or the mark that every
// value the bucket held when the watch began has been delivered (`caughtUp`).
struct KvChange {
  bool caughtUp = false;
  bool deleted = false;
  std::string key;
  std::vector<std::uint8_t> value;
  std::uint64_t revision = 0;
};

class KvWatcher {
 public:
  KvWatcher() = default;
  explicit KvWatcher(__kvWatcher* w) : w_(w) {}
  // The next change within `timeoutSeconds`; nothing when none came. An Error when the
  // watcher broke (its connection closed).
  Result<std::optional<KvChange>> next(double timeoutSeconds);
  explicit operator bool() const { return w_ != nullptr; }

 private:
  struct Free {
    void operator()(__kvWatcher* w) const;
  };
  std::unique_ptr<__kvWatcher, Free> w_;
};

class KvBucket {
 public:
  KvBucket() = default;
  KvBucket(__kvStore* kv, std::string name) : kv_(kv), name_(std::move(name)) {}
  // Stores `value` as `key`'s newest value; returns its revision.
  Result<std::uint64_t> put(const std::string& key, std::span<const std::uint8_t> value);
  // `key`'s current value; nothing when it has none.
  Result<std::optional<std::vector<std::uint8_t>>> get(const std::string& key);
  // Every key's current value first (then a KvChange with caughtUp), then each change as it
  // happens.
  Result<KvWatcher> watchAll();
  const std::string& name() const { return name_; }
  explicit operator bool() const { return kv_ != nullptr; }

 private:
  struct Free {
    void operator()(__kvStore* kv) const;
  };
  std::unique_ptr<__kvStore, Free> kv_;
  std::string name_;
};

struct NatsMessage {
  std::string subject;
  std::vector<std::uint8_t> data;
};

class NatsSubscription {
 public:
  NatsSubscription() = default;
  explicit NatsSubscription(__natsSubscription* s) : s_(s) {}
  // The next message within `timeoutSeconds`; nothing when none came.
  Result<std::optional<NatsMessage>> next(double timeoutSeconds);
  explicit operator bool() const { return s_ != nullptr; }

 private:
  struct Free {
    void operator()(__natsSubscription* s) const;
  };
  std::unique_ptr<__natsSubscription, Free> s_;
};

class NatsConnection {
 public:
  // Connects to one of the servers; an Error names the URLs and why none answered.
  static Result<NatsConnection> connect(const NatsOptions& options);
  NatsConnection() = default;

  // Core NATS: a message on `subject`, delivered to whoever subscribes now (no storage).
  Status publish(const std::string& subject, std::span<const std::uint8_t> data);
  // Messages on `subject` (wildcards allowed), read with next().
  Result<NatsSubscription> subscribe(const std::string& subject);
  // Waits until the server has seen everything published so far.
  Status flush(double timeoutSeconds);
  bool connected() const;
  // The largest message the server takes (its max_payload), 0 before connecting.
  std::int64_t maxPayload() const;

  // The bucket, created with `options` where it does not exist yet.
  Result<KvBucket> createBucket(const BucketOptions& options);
  // An existing bucket; an Error when there is none of that name.
  Result<KvBucket> openBucket(const std::string& name);

  explicit operator bool() const { return nc_ != nullptr; }

 private:
  struct FreeConnection {
    void operator()(__natsConnection* nc) const;
  };
  struct FreeJs {
    void operator()(__jsCtx* js) const;
  };
  // The JetStream context borrows the connection, so it is declared after it (freed first).
  std::unique_ptr<__natsConnection, FreeConnection> nc_;
  std::unique_ptr<__jsCtx, FreeJs> js_;
};

}  // namespace pc::relay
