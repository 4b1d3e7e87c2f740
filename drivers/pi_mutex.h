// A mutex with priority inheritance, for locks a real-time thread shares with normal ones.
#pragma once

#include <pthread.h>

namespace rheo::drivers {

/// Lockable (std::lock_guard, std::unique_lock, try_to_lock). While a SCHED_FIFO thread waits,
/// the holder runs at the waiter's priority, so a normal-priority holder that other work
/// preempts cannot stall the real-time thread for longer than its own critical section
/// (a plain std::mutex allows that priority inversion).
class PiMutex {
 public:
  PiMutex() {
    pthread_mutexattr_t attr;
    pthread_mutexattr_init(&attr);
    pthread_mutexattr_setprotocol(&attr, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&mutex_, &attr);
    pthread_mutexattr_destroy(&attr);
  }
  ~PiMutex() { pthread_mutex_destroy(&mutex_); }
  PiMutex(const PiMutex&) = delete;
  PiMutex& operator=(const PiMutex&) = delete;

  void lock() { pthread_mutex_lock(&mutex_); }
  bool try_lock() { return pthread_mutex_trylock(&mutex_) == 0; }
  void unlock() { pthread_mutex_unlock(&mutex_); }

 private:
  pthread_mutex_t mutex_;
};

}  // namespace rheo::drivers
