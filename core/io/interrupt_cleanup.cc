#include "core/io/interrupt_cleanup.h"

#include <fcntl.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstring>

namespace bodymodel {

bool is_atomic_write_temporary(const char* name, long pid) {
  if (name == nullptr || name[0] != '.') return false;
  // The last ".tmp" must be followed by exactly "<pid>_<digits>" up to the end.
  const char* tmp = nullptr;
  for (const char* p = std::strstr(name + 1, ".tmp"); p; p = std::strstr(p + 1, ".tmp")) tmp = p;
  if (tmp == nullptr || tmp == name + 1) return false;  // needs a non-empty final name
  const char* p = tmp + 4;
  char digits[24];
  int n = 0;
  for (long v = pid; n < 23; v /= 10) {  // pid in decimal, reversed
    digits[n++] = static_cast<char>('0' + v % 10);
    if (v < 10) break;
  }
  while (n > 0)
    if (*p++ != digits[--n]) return false;
  if (*p++ != '_') return false;
  if (*p < '0' || *p > '9') return false;
  while (*p >= '0' && *p <= '9') ++p;
  return *p == '\0';
}

int remove_open_temporaries() {
#if defined(__linux__) && defined(SYS_getdents64)
  const long pid = static_cast<long>(::getpid());
  const int dir = ::open("/proc/self/fd", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir < 0) return 0;
  struct LinuxDirent64 {  // the kernel's record (linux/dirent.h)
    uint64_t d_ino;
    int64_t d_off;
    unsigned short d_reclen;
    unsigned char d_type;
    char d_name[1];
  };
  int removed = 0;
  alignas(8) char buf[4096];
  for (;;) {
    const long n = ::syscall(SYS_getdents64, dir, buf, sizeof buf);
    if (n <= 0) break;
    for (long off = 0; off < n;) {
      const auto* d = reinterpret_cast<const LinuxDirent64*>(buf + off);
      off += d->d_reclen;
      if (d->d_name[0] < '0' || d->d_name[0] > '9') continue;  // ".", ".."
      char link[64] = "/proc/self/fd/";
      const size_t len = std::strlen(link), name_len = std::strlen(d->d_name);
      if (len + name_len + 1 > sizeof link) continue;
      std::memcpy(link + len, d->d_name, name_len + 1);
      char target[4096];
      const ssize_t t = ::readlink(link, target, sizeof target - 1);
      if (t <= 0) continue;
      target[t] = '\0';
      const char* base = std::strrchr(target, '/');
      base = base ? base + 1 : target;
      if (is_atomic_write_temporary(base, pid) && ::unlink(target) == 0) ++removed;
    }
  }
  ::close(dir);
  return removed;
#else
  return 0;
#endif
}

namespace {

void on_interrupt(int sig) {
  const int saved_errno = errno;
  remove_open_temporaries();
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  sigemptyset(&dfl.sa_mask);
  ::sigaction(sig, &dfl, nullptr);
  errno = saved_errno;
  ::raise(sig);  // delivered on return from this handler: the default action ends the process
}

}  // namespace

void install_interrupt_cleanup() {
  static std::atomic<bool> installed{false};
  if (installed.exchange(true)) return;
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) continue;
    struct sigaction sa {};
    sa.sa_handler = on_interrupt;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;
    ::sigaction(sig, &sa, nullptr);
  }
}

}  // namespace bodymodel
