#include "wake_probe.hpp"

#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <system_error>
#include <thread>

namespace fabrik::bench {

namespace {

using Clock = std::chrono::steady_clock;

double us_since(Clock::time_point t0, Clock::time_point t1) {
  return std::chrono::duration<double, std::micro>(t1 - t0).count();
}

int checked(int fd, const char* what) {
  if (fd < 0) throw std::system_error(errno, std::generic_category(), what);
  return fd;
}

void write_one(int fd) {
  const std::uint64_t one = 1;
  [[maybe_unused]] const auto n = ::write(fd, &one, sizeof one);
}

}  // namespace

WakeProbe::WakeProbe() {
  wake_fd_ = checked(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC), "eventfd");
  idle_fd_ = checked(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC), "eventfd");
  epoll_fd_ = checked(::epoll_create1(EPOLL_CLOEXEC), "epoll_create1");
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.fd = wake_fd_;
  checked(::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &ev), "epoll_ctl");
  thread_ = std::thread([this] { sleeper(); });
}

WakeProbe::~WakeProbe() {
  stop_ = true;
  write_one(wake_fd_);
  thread_.join();
  ::close(epoll_fd_);
  ::close(idle_fd_);
  ::close(wake_fd_);
}

void WakeProbe::sleeper() {
  while (!stop_.load()) {
    epoll_event ev{};
    // Bounded, so a lost wake cannot keep the destructor waiting.
    if (::epoll_wait(epoll_fd_, &ev, 1, 100) <= 0) continue;
    std::uint64_t count = 0;
    if (::read(wake_fd_, &count, sizeof count) == sizeof count) woken_ += count;
  }
}

double WakeProbe::wake_sleeping_us(std::chrono::milliseconds previous_within) {
  // The previous wake taken: the sleeper is on its way back into epoll_wait
  // (between frames it has long arrived there).
  const Clock::time_point deadline = Clock::now() + previous_within;
  // Yielding, so that on a busy machine this wait does not hold back the sleeper it waits for.
  while (woken_.load() < written_) {
    if (Clock::now() > deadline) return -1.0;
    std::this_thread::yield();
  }
  const Clock::time_point t0 = Clock::now();
  write_one(wake_fd_);
  const Clock::time_point t1 = Clock::now();
  ++written_;
  return us_since(t0, t1);
}

double WakeProbe::write_alone_us() {
  const Clock::time_point t0 = Clock::now();
  write_one(idle_fd_);
  const Clock::time_point t1 = Clock::now();
  std::uint64_t count = 0;
  [[maybe_unused]] const auto n = ::read(idle_fd_, &count, sizeof count);
  return us_since(t0, t1);
}

}  // namespace fabrik::bench
