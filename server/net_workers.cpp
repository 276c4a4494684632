#include "net_workers.h"

#include <pthread.h>

#include <algorithm>

namespace pc {

NetWorkers::NetWorkers(int threads, const std::string& name) {
  for (int i = 1; i < std::max(threads, 1); ++i) {
    threads_.emplace_back([this, name] {
      pthread_setname_np(pthread_self(), name.substr(0, 15).c_str());
      work();
    });
  }
}

NetWorkers::~NetWorkers() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void NetWorkers::take() {
  for (std::size_t i = next_.fetch_add(1); i < parts_; i = next_.fetch_add(1)) (*part_)(i);
}

void NetWorkers::run(std::size_t parts, const std::function<void(std::size_t)>& part) {
  if (threads_.empty() || parts <= 1) {
    for (std::size_t i = 0; i < parts; ++i) part(i);
    return;
  }
  {
    std::lock_guard lock(mutex_);
    part_ = &part;
    parts_ = parts;
    next_ = 0;
    busy_ = int(threads_.size());
    ++generation_;
  }
  wake_.notify_all();
  take();
  std::unique_lock lock(mutex_);
  done_.wait(lock, [this] { return busy_ == 0; });
  part_ = nullptr;
}

void NetWorkers::work() {
  std::uint64_t seen = 0;
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
    }
    take();
    std::lock_guard lock(mutex_);
    if (--busy_ == 0) done_.notify_one();
  }
}

}  // namespace pc
