// What this machine charges a thread for waking another that sleeps in
// epoll_wait: an eventfd write, as ZeroMQ wakes its I/O thread once per
// send when the I/O thread is idle. On a virtual machine this can cost the
// writer several microseconds (waking an idle vCPU likely goes through the
// hypervisor); `fabrik bench pipeline` samples it between frames so that its send figure
// can be read against it.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>

namespace fabrik::bench {

class WakeProbe {
 public:
  WakeProbe();  // throws std::system_error when eventfd or epoll fail
  ~WakeProbe();
  WakeProbe(const WakeProbe&) = delete;
  WakeProbe& operator=(const WakeProbe&) = delete;

  // The writer's time for one eventfd write that wakes the sleeping thread,
  // in microseconds; negative when the thread had not taken the previous wake
  // within `previous_within` (no sample). The bench keeps that short, so a
  // busy machine costs it samples, not time; a test waits longer, so that
  // only a wake lost for good fails it.
  double wake_sleeping_us(
      std::chrono::milliseconds previous_within = std::chrono::milliseconds(10));
  // The same write with no thread waiting on it: the system call alone.
  double write_alone_us();

 private:
  void sleeper();
  int wake_fd_ = -1;
  int idle_fd_ = -1;
  int epoll_fd_ = -1;
  std::atomic<std::uint64_t> woken_{0};
  std::uint64_t written_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace fabrik::bench
