// The threads that share the network thread's heaviest work: polling the senders of datagram
// sessions, sealing their datagrams and handing them to the socket. With a thousand clients
// that work is more than one core does (one thread spent 993 ms of CPU per second at 1,000
// clients of 1 Mbit/s), and every client of that thread then falls behind together.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace pc {

class NetWorkers {
 public:
  // `threads` in all, the caller of run() included (at least 1: then run() is a plain loop).
  // Each started thread is named `name`, so that CPU figures by thread name count them with
  // the thread that calls run().
  NetWorkers(int threads, const std::string& name);
  ~NetWorkers();
  NetWorkers(const NetWorkers&) = delete;
  NetWorkers& operator=(const NetWorkers&) = delete;

  int threads() const { return int(threads_.size()) + 1; }
  // Calls part(i) for every i in [0, parts) on this thread and the started ones, each i once,
  // and returns when all have returned. `part` must not throw.
  void run(std::size_t parts, const std::function<void(std::size_t)>& part);

 private:
  void work();
  void take();  // runs parts until none is left

  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::uint64_t generation_ = 0;  // one per run()
  bool stop_ = false;
  const std::function<void(std::size_t)>* part_ = nullptr;
  std::size_t parts_ = 0;
  std::atomic<std::size_t> next_{0};
  int busy_ = 0;  // started threads still inside the current run
};

}  // namespace pc
