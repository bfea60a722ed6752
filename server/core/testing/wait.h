// WaitUntil: the one way the server's tests wait for what other threads or the server do.
// They wait for events, never for a time: a test that must hold work at a point uses a gate
// (ServerOptions::before_work), and this only bounds a wait that a hang would make endless.
#ifndef ACTOPO_SERVER_CORE_TESTING_WAIT_H_
#define ACTOPO_SERVER_CORE_TESTING_WAIT_H_

#include <chrono>
#include <thread>

namespace actopo::testing {

// Whether done() holds within `timeout` (checked now, then every millisecond).
template <class Done>
bool WaitUntil(Done&& done, std::chrono::milliseconds timeout = std::chrono::seconds(60)) {
  const auto give_up = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() >= give_up) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

}  // namespace actopo::testing

#endif  // ACTOPO_SERVER_CORE_TESTING_WAIT_H_
