// `bodymodel serve`'s connection handling around cpp-httplib (included by serve.cc only).
//
// cpp-httplib gives every connection a pool thread from accept to close, and times out each read
// on its own: 8 clients sending a header line every few seconds held all 8 threads indefinitely
// and every other request waited (slowloris). Here one poller thread holds the connections while
// their requests arrive, and hands a connection to a worker only once its whole request is in:
// the headers and a body within --max-body (Content-Length or chunked). A request must arrive
// within `request_timeout` of its first byte (408, then closed), an idle kept-alive connection is
// closed after the same time, and when more than `max_pending` connections wait the one waiting
// longest is closed. Workers then parse and answer from the buffered bytes with cpp-httplib's
// own request processing (Server::process_request), reading the socket only for bodies the poller
// did not wait for (oversized or Expect: 100-continue), within the same deadline.
//
// Hook points: cpp-httplib calls the virtual process_and_close_socket() for each accepted socket
// through the task queue; with a queue that runs tasks inline, the accept thread passes the socket
// to the poller and returns at once.
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

namespace bodymodel::serve {

using Clock = std::chrono::steady_clock;

// Set by a handler that answered without reading the request's whole body: the rest of the
// connection's bytes are not a next request, so the connection is closed after the answer.
inline thread_local bool t_close_connection = false;

struct ConnectionLimits {
  size_t max_body = 16 * 1024;
  std::chrono::milliseconds request_timeout{5000};  // whole request, and idle keep-alive
  int workers = 8;
  size_t max_pending = 512;  // connections waiting for their request
  int keep_alive_requests = 20;
};

struct Connection {
  int fd = -1;
  std::string buf;  // received, not yet consumed
  size_t pos = 0;   // consumed prefix of buf
  Clock::time_point deadline, waiting_since;
  bool idle = true;       // no byte of the next request yet
  bool draining = false;  // answered early: read and discard until EOF or the deadline
  int served = 0;
  ~Connection() {
    if (fd >= 0) {
      ::shutdown(fd, SHUT_RDWR);
      ::close(fd);
    }
  }
  size_t buffered() const { return buf.size() - pos; }
};

// Where a request's header block ends in s (index just after the blank line), or npos.
inline size_t header_end(const std::string& s, size_t from) {
  for (size_t i = s.find('\n', from); i != std::string::npos; i = s.find('\n', i + 1)) {
    if (i + 1 < s.size() && s[i + 1] == '\n') return i + 2;
    if (i + 2 < s.size() && s[i + 1] == '\r' && s[i + 2] == '\n') return i + 3;
  }
  return std::string::npos;
}

inline std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The value of header `name` (lower case) in the header block, trimmed; empty when absent.
inline std::string header_value(const std::string& block, const std::string& name) {
  size_t line = block.find('\n');  // skip the request line
  while (line != std::string::npos && line + 1 < block.size()) {
    const size_t start = line + 1, end = block.find('\n', start);
    const std::string l = block.substr(start, end == std::string::npos ? std::string::npos : end - start);
    const size_t colon = l.find(':');
    if (colon != std::string::npos && lower(l.substr(0, colon)) == name) {
      size_t a = colon + 1, b = l.size();
      while (a < b && std::isspace(static_cast<unsigned char>(l[a]))) ++a;
      while (b > a && std::isspace(static_cast<unsigned char>(l[b - 1]))) --b;
      return l.substr(a, b - a);
    }
    line = end;
  }
  return {};
}

// Whether the chunked body starting at s[from] is complete (the last chunk and the trailers'
// blank line are in). Malformed framing counts as complete: cpp-httplib then answers 400.
inline bool chunked_complete(const std::string& s, size_t from) {
  size_t p = from;
  while (true) {
    const size_t eol = s.find('\n', p);
    if (eol == std::string::npos) return false;
    size_t size = 0, digits = 0;
    for (size_t i = p; i < eol && std::isxdigit(static_cast<unsigned char>(s[i])); ++i, ++digits) {
      if (size > (size_t{1} << 40)) return true;  // absurd: let the parser refuse it
      size = size * 16 + static_cast<size_t>(std::isdigit(static_cast<unsigned char>(s[i])) ? s[i] - '0'
                                                                                           : std::tolower(s[i]) - 'a' + 10);
    }
    if (digits == 0) return true;
    p = eol + 1;
    if (size == 0) {  // trailers until a blank line
      while (true) {
        const size_t e = s.find('\n', p);
        if (e == std::string::npos) return false;
        const bool blank = e == p || (e == p + 1 && s[p] == '\r');
        p = e + 1;
        if (blank) return true;
      }
    }
    if (s.size() - p < size + 1) return false;
    p += size;
    if (s[p] == '\r') ++p;
    if (p >= s.size()) return false;
    if (s[p] != '\n') return true;
    ++p;
  }
}

// Whether c's buffer holds a request a worker can answer without waiting for the client: the
// whole header block, and the body when it is announced within `max_body`. Requests the worker
// refuses anyway (header block or body too large, Expect: 100-continue) are ready at once.
inline bool request_ready(const Connection& c, size_t max_body) {
  constexpr size_t kMaxHeaders = CPPHTTPLIB_REQUEST_URI_MAX_LENGTH + CPPHTTPLIB_HEADER_MAX_LENGTH;
  const size_t end = header_end(c.buf, c.pos);
  if (end == std::string::npos) return c.buffered() > kMaxHeaders;
  const std::string block = c.buf.substr(c.pos, end - c.pos);
  if (lower(header_value(block, "expect")) == "100-continue") return true;
  const size_t body = c.buf.size() - end;
  if (lower(header_value(block, "transfer-encoding")).find("chunked") != std::string::npos)
    return body > max_body + 4096 || chunked_complete(c.buf, end);
  const std::string length = header_value(block, "content-length");
  if (length.empty()) return true;
  char* stop = nullptr;
  const unsigned long long n = std::strtoull(length.c_str(), &stop, 10);
  if (*stop != '\0' || n > max_body) return true;
  return body >= n;
}

// A cpp-httplib Stream over a connection: the buffered bytes first, then the socket, every read
// and write bounded by one deadline per request.
class ConnectionStream : public httplib::Stream {
 public:
  ConnectionStream(Connection& c, Clock::time_point read_deadline, std::chrono::milliseconds write_time)
      : c_(c), read_deadline_(read_deadline), write_time_(write_time) {}

  bool is_readable() const override { return c_.buffered() > 0 || wait(POLLIN, read_deadline_); }
  bool is_writable() const override { return wait(POLLOUT, write_deadline()); }

  ssize_t read(char* ptr, size_t size) override {
    if (c_.buffered() > 0) {
      const size_t n = std::min(size, c_.buffered());
      std::memcpy(ptr, c_.buf.data() + c_.pos, n);
      c_.pos += n;
      return static_cast<ssize_t>(n);
    }
    if (!wait(POLLIN, read_deadline_)) return -1;
    const ssize_t n = ::recv(c_.fd, ptr, size, MSG_DONTWAIT);
    return n < 0 && (errno == EAGAIN || errno == EINTR) ? 0 : n;
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (!wait(POLLOUT, write_deadline())) return -1;
    const ssize_t n = ::send(c_.fd, ptr, size, MSG_DONTWAIT | MSG_NOSIGNAL);
    return n < 0 && (errno == EAGAIN || errno == EINTR) ? 0 : n;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override { address(false, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { address(true, ip, port); }
  socket_t socket() const override { return c_.fd; }

 private:
  // The answer's writes share one deadline, from the first write (the handler's work before it
  // does not count).
  Clock::time_point write_deadline() const {
    if (!write_started_) {
      write_started_ = true;
      write_deadline_ = Clock::now() + write_time_;
    }
    return write_deadline_;
  }
  bool wait(short events, Clock::time_point deadline) const {
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
      if (left <= 0) return false;
      pollfd p{c_.fd, events, 0};
      const int r = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 1000)));
      if (r > 0) return (p.revents & (events | POLLHUP | POLLERR)) != 0;
      if (r < 0 && errno != EINTR) return false;
    }
  }
  void address(bool local, std::string& ip, int& port) const {
    sockaddr_storage a{};
    socklen_t len = sizeof a;
    const int r = local ? ::getsockname(c_.fd, reinterpret_cast<sockaddr*>(&a), &len)
                        : ::getpeername(c_.fd, reinterpret_cast<sockaddr*>(&a), &len);
    char text[INET6_ADDRSTRLEN] = "";
    port = 0;
    if (r == 0 && a.ss_family == AF_INET) {
      const auto* in = reinterpret_cast<const sockaddr_in*>(&a);
      ::inet_ntop(AF_INET, &in->sin_addr, text, sizeof text);
      port = ntohs(in->sin_port);
    } else if (r == 0 && a.ss_family == AF_INET6) {
      const auto* in = reinterpret_cast<const sockaddr_in6*>(&a);
      ::inet_ntop(AF_INET6, &in->sin6_addr, text, sizeof text);
      port = ntohs(in->sin6_port);
    }
    ip = text;
  }

  Connection& c_;
  Clock::time_point read_deadline_;
  std::chrono::milliseconds write_time_;
  mutable bool write_started_ = false;
  mutable Clock::time_point write_deadline_;
};

// Runs tasks on the calling thread: the accept loop's only task is handing the socket over.
class InlineQueue : public httplib::TaskQueue {
 public:
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override {}
};

class GatedServer : public httplib::Server {
 public:
  explicit GatedServer(ConnectionLimits limits) : limits_(limits) {
    new_task_queue = [] { return new InlineQueue; };
    wake_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    poller_ = std::thread([this] { poll_loop(); });
    for (int i = 0; i < std::max(1, limits_.workers); ++i) workers_.emplace_back([this] { work_loop(); });
  }
  ~GatedServer() override { shut_down(); }

  // After listen_after_bind() returned: closes waiting connections, lets the workers finish the
  // requests they are answering, joins the threads.
  void shut_down() {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;
      stopping_ = true;
    }
    notify_poller();
    ready_cv_.notify_all();
    if (poller_.joinable()) poller_.join();
    for (auto& w : workers_)
      if (w.joinable()) w.join();
    if (wake_ >= 0) ::close(wake_);
    wake_ = -1;
  }

 private:
  bool process_and_close_socket(socket_t sock) override {
    auto c = std::make_unique<Connection>();
    c->fd = sock;
    c->waiting_since = Clock::now();
    c->deadline = c->waiting_since + limits_.request_timeout;
    hand_to_poller(std::move(c));
    return true;
  }

  void hand_to_poller(std::unique_ptr<Connection> c) {
    {
      std::lock_guard lock(mutex_);
      if (stopping_) return;  // closed by ~Connection
      incoming_.push_back(std::move(c));
    }
    notify_poller();
  }
  void notify_poller() {
    const uint64_t one = 1;
    if (wake_ < 0) return;
    [[maybe_unused]] const ssize_t r = ::write(wake_, &one, sizeof one);
  }

  // A timed-out request gets a 408 (best effort: one non-blocking send) before the close.
  static void refuse_late(const Connection& c) {
    static const char kReply[] = "HTTP/1.1 408 Request Timeout\r\nConnection: close\r\nContent-Length: 0\r\n\r\n";
    if (!c.idle && !c.draining) ::send(c.fd, kReply, sizeof kReply - 1, MSG_DONTWAIT | MSG_NOSIGNAL);
  }

  void poll_loop() {
    std::vector<std::unique_ptr<Connection>> pending;
    std::vector<pollfd> fds;
    std::vector<char> scratch(64 * 1024);
    while (true) {
      {
        std::lock_guard lock(mutex_);
        if (stopping_) return;  // pending connections close with the vector
        for (auto& c : incoming_) pending.push_back(std::move(c));
        incoming_.clear();
      }
      // Kept-alive connections may already hold their next request (pipelining).
      for (auto& c : pending)
        if (c && !c->draining && c->buffered() > 0 && request_ready(*c, limits_.max_body)) to_workers(std::move(c));
      // Over the cap: close the connections waiting longest.
      pending.erase(std::remove(pending.begin(), pending.end(), nullptr), pending.end());
      if (pending.size() > limits_.max_pending) {
        std::sort(pending.begin(), pending.end(),
                  [](const auto& a, const auto& b) { return a->waiting_since < b->waiting_since; });
        for (size_t i = 0; i < pending.size() - limits_.max_pending; ++i) refuse_late(*pending[i]);
        pending.erase(pending.begin(), pending.begin() + static_cast<long>(pending.size() - limits_.max_pending));
      }
      const auto now = Clock::now();
      auto next = now + std::chrono::seconds(1);
      fds.assign(1, pollfd{wake_, POLLIN, 0});
      for (auto& c : pending) {
        fds.push_back({c->fd, POLLIN, 0});
        next = std::min(next, c->deadline);
      }
      const auto wait_ms = std::chrono::duration_cast<std::chrono::milliseconds>(next - now).count();
      const int r = ::poll(fds.data(), fds.size(), static_cast<int>(std::max<long long>(0, wait_ms) + 1));
      if (r < 0 && errno != EINTR) return;
      if (fds[0].revents & POLLIN) {
        uint64_t n;
        [[maybe_unused]] const ssize_t rr = ::read(wake_, &n, sizeof n);
      }
      const auto t = Clock::now();
      for (size_t i = 0; i < pending.size(); ++i) {
        auto& c = pending[i];
        if (fds[i + 1].revents) {
          if (!receive(*c, scratch, t)) {
            c.reset();
            continue;
          }
          if (!c->draining && request_ready(*c, limits_.max_body)) {
            to_workers(std::move(c));
            continue;
          }
        }
        if (t >= c->deadline) {
          refuse_late(*c);
          c.reset();
        }
      }
      pending.erase(std::remove(pending.begin(), pending.end(), nullptr), pending.end());
    }
  }

  // Reads what the socket has; false when the connection is finished (EOF, error, or a
  // draining connection's end).
  bool receive(Connection& c, std::vector<char>& scratch, Clock::time_point now) {
    // What a request may hold: header block plus body, plus framing of a chunked body.
    const size_t cap = CPPHTTPLIB_REQUEST_URI_MAX_LENGTH + CPPHTTPLIB_HEADER_MAX_LENGTH + limits_.max_body + 8192;
    for (int reads = 0; reads < 16; ++reads) {  // bounded: one client cannot hold the poller
      const size_t room = c.draining ? scratch.size() : std::min(scratch.size(), cap - std::min(cap, c.buffered()));
      if (room == 0) return true;  // request_ready() says yes at this size
      const ssize_t n = ::recv(c.fd, scratch.data(), room, MSG_DONTWAIT);
      if (n == 0) return false;
      if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
      if (c.draining) continue;
      if (c.pos > 0 && c.pos == c.buf.size()) c.buf.clear(), c.pos = 0;
      c.buf.append(scratch.data(), static_cast<size_t>(n));
      if (c.idle) {  // the request's time starts with its first byte
        c.idle = false;
        c.deadline = now + limits_.request_timeout;
      }
    }
    return true;
  }

  void to_workers(std::unique_ptr<Connection> c) {
    {
      std::lock_guard lock(mutex_);
      ready_.push_back(std::move(c));
    }
    ready_cv_.notify_one();
  }

  void work_loop() {
    while (true) {
      std::unique_ptr<Connection> c;
      {
        std::unique_lock lock(mutex_);
        ready_cv_.wait(lock, [this] { return stopping_ || !ready_.empty(); });
        if (ready_.empty()) return;  // stopping
        c = std::move(ready_.front());
        ready_.pop_front();
      }
      serve_one(std::move(c));
    }
  }

  void serve_one(std::unique_ptr<Connection> c) {
    const bool last = ++c->served >= limits_.keep_alive_requests;
    bool closed = false, ok = false;
    t_close_connection = false;
    {
      ConnectionStream strm(*c, Clock::now() + limits_.request_timeout, limits_.request_timeout);
      try {
        ok = process_request(strm, last, closed, nullptr);
      } catch (...) {
        ok = false;
      }
    }
    if (c->pos > 0) c->buf.erase(0, c->pos), c->pos = 0;
    if (t_close_connection) {
      // The client may still be sending the body we did not read: closing now would reset the
      // connection and could lose the answer on its side. Stop writing and discard its bytes a
      // while first.
      ::shutdown(c->fd, SHUT_WR);
      c->draining = true;
      c->buf.clear();
      c->deadline = Clock::now() + std::chrono::seconds(2);
      hand_to_poller(std::move(c));
      return;
    }
    if (!ok || closed || last) return;  // closed by ~Connection
    c->idle = c->buffered() == 0;
    c->waiting_since = Clock::now();
    c->deadline = c->waiting_since + limits_.request_timeout;
    hand_to_poller(std::move(c));
  }

  ConnectionLimits limits_;
  int wake_ = -1;
  std::mutex mutex_;
  bool stopping_ = false;
  std::vector<std::unique_ptr<Connection>> incoming_;
  std::deque<std::unique_ptr<Connection>> ready_;
  std::condition_variable ready_cv_;
  std::thread poller_;
  std::vector<std::thread> workers_;
};

}  // namespace bodymodel::serve
