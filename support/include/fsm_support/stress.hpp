#pragma once

/// @file fsm_support/stress.hpp
/// @brief A competing busy process for as long as an object lives: the `--stress` option of the
/// demo and `servo_latency`, which measure the servo loop with another process taking a core.

#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <vector>

namespace fsm::support {

/// @brief Forks `count` child processes that spin on the CPU until this object is destroyed
/// (SIGKILL, then reaped). The children are separate processes at the default priority, as
/// another program on the user's machine would be.
class BusyProcesses {
 public:
  explicit BusyProcesses(int count) {
    for (int k = 0; k < count; ++k) {
      const pid_t pid = fork();
      if (pid == 0) {
        volatile unsigned long x = 0;
        for (;;) x = x * 6364136223846793005ul + 1442695040888963407ul;  // until killed
      }
      if (pid > 0) m_children.push_back(pid);
      if (pid < 0) std::perror("fork (--stress)");
    }
  }
  ~BusyProcesses() {
    for (const pid_t pid : m_children) kill(pid, SIGKILL);
    for (const pid_t pid : m_children) waitpid(pid, nullptr, 0);
  }
  BusyProcesses(const BusyProcesses&) = delete;
  BusyProcesses& operator=(const BusyProcesses&) = delete;
  [[nodiscard]] int count() const noexcept { return int(m_children.size()); }

 private:
  std::vector<pid_t> m_children;
};

}  // namespace fsm::support
