// `bodymodel serve model.npz`: live morphing in the browser. A small HTTP/JSON API (cpp-httplib)
// around one ShapeMorpher, and a page with a slider per label, a seed box for generate, the
// measured labels and OBJ / glb downloads. Loopback by default; request bodies are capped however
// they are framed, a request must arrive whole within --timeout and only whole requests occupy a
// thread (serve_connections.h), and at most --max-decodes morphs run at once (others get 503 at
// once, so a flood cannot queue unbounded work or memory).
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <csignal>
#include <memory>
#include <mutex>
#include <thread>

#include <sys/socket.h>  // listen(): the backlog, below

#include "core/error.h"
#include "core/io/atomic_write.h"
#include "core/io/json_text.h"
#include "model/morph.h"
#include "model/shape_preview.h"
#include "skinning/gltf_export.h"
#include "tools/console.h"
#include "tools/verb.h"
#include "tools/verbs/model_common.h"
#include "tools/viewer/viewer_assets.h"
// Last: it pulls in <httplib.h> and so <resolv.h>, whose _res macro breaks Eigen headers parsed
// after it.
#include "tools/verbs/serve_connections.h"

namespace bodymodel {
namespace {
namespace fs = std::filesystem;
using cli::base64;
using nlohmann::json;

struct ServeArgs {
  std::string model, host = "127.0.0.1", three;
  int port = 8080, max_decodes = 2, threads = 8, timeout = 5;
  size_t max_body = 16 * 1024;
  bool preview = true;
};

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// A request that cannot be served as asked: answered 400 with this message.
struct BadRequest : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class MorphService {
 public:
  MorphService(std::shared_ptr<const BodyModel> model, int max_decodes, bool preview)
      : model_(std::move(model)), morpher_(model_), max_decodes_(max_decodes),
        x0_(Eigen::VectorXd::Zero(model_->tmpl->encoding_size())), c0_(model_->shape.pca.project(x0_)) {
    // The drag preview (2·K decodes) is built behind the server's back: until it is ready,
    // quick requests decode once.
    if (preview)
      preview_thread_ = std::thread([this] {
        try {
          auto p = std::make_shared<const ShapePreview>(morpher_, x0_, &stop_);
          if (p->ready()) std::atomic_store(&preview_, p);
        } catch (const std::exception& e) {
          cli::warn(std::string("no drag preview: ") + e.what());
        }
      });
  }
  ~MorphService() {
    stop_ = true;
    if (preview_thread_.joinable()) preview_thread_.join();
  }

  const BodyModel& model() const { return *model_; }

  json describe() const {
    json j;
    for (auto& l : model_->shape.regression.labels)
      j["labels"].push_back({{"name", l.name}, {"unit", l.unit}, {"min", l.min}, {"max", l.max}, {"mean", l.mean},
                             {"measured", is_measurable_label(l.name)}});
    const auto& F = model_->tmpl->faces();
    std::vector<uint32_t> f;
    for (int i = 0; i < F.rows(); ++i)
      for (int k = 0; k < 3; ++k) f.push_back(static_cast<uint32_t>(F(i, k)));
    j["faces"] = base64(f.data(), f.size() * 4);
    j["vertex_count"] = model_->tmpl->vertex_count();
    return j;
  }

  // The request's conditions, checked as the CLI checks --set / --where values: numbers (sex
  // also female/male) and not far outside the data (the CLI warns there; the server refuses).
  std::vector<LabelCondition> conditions(const json& body) const {
    std::vector<LabelCondition> out;
    if (!body.contains("labels")) return out;
    if (!body["labels"].is_object()) throw BadRequest("'labels' must be an object of label: value");
    const SemanticRegression& reg = model_->shape.regression;
    for (auto& [name, v] : body["labels"].items()) {
      double value;
      if (v.is_number()) value = v.get<double>();
      else if (v.is_string()) value = model_cli::parse_label_value(name, v.get<std::string>());
      else throw BadRequest(fmt::format("value of '{}' must be a number", name));
      const int i = reg.index(name);  // InputError listing the labels when unknown
      if (!std::isfinite(value)) throw BadRequest(fmt::format("value of '{}' must be finite", name));
      const LabelInfo& info = reg.labels[static_cast<size_t>(i)];
      const double range = info.max - info.min;
      if (value < info.min - 0.25 * range || value > info.max + 0.25 * range)
        throw BadRequest(fmt::format("{} = {} is far outside the data ({:.4g} .. {:.4g} {})", info.name, value, info.min,
                                     info.max, info.unit));
      out.push_back(LabelCondition::exact(name, value));
    }
    return out;
  }

  struct Body {
    Eigen::MatrixX3d V;
    BodyMeasurements measured;
    double seconds = 0;
    bool preview = false;  // V is ShapePreview's first-order approximation, not a decode
    // Where the time went (ms): the last decode's stages (DecodeTiming; the last of this
    // request's decodes unless another request decoded meanwhile), the decodes, measuring.
    DecodeTiming last_decode;
    int decodes = 0;
    double decode_ms = 0, measure_ms = 0;
  };

  // Morph of the mean body to the labels, or (with "seed") a generated body meeting them.
  Body make(const json& body) {
    const auto cond = conditions(body);
    uint64_t seed = 0;
    const bool generate = body.contains("seed");
    if (generate) {
      if (!body["seed"].is_number_integer() || body["seed"].get<long long>() < 0)
        throw BadRequest("'seed' must be a non-negative integer");
      seed = body["seed"].get<uint64_t>();
    }
    struct Slot {  // the cap on concurrent decodes
      std::atomic<int>& n;
      ~Slot() { --n; }
    };
    if (++running_ > max_decodes_) {
      --running_;
      throw std::overflow_error(fmt::format("busy: {} decodes running (--max-decodes)", max_decodes_));
    }
    Slot slot{running_};
    const auto t0 = std::chrono::steady_clock::now();
    Body b;
    Sex sex = Sex::unknown;
    for (auto& c : cond)
      if (c.label == "sex") sex = c.lo < 0.5 ? Sex::female : Sex::male;
    if (generate) {
      GenerateOptions o;
      GeneratedBody g = generate_body(morpher_, cond, seed, o);
      b.V = std::move(g.V);
      b.measured = g.measured;
    } else {
      MorphOptions o;
      o.sex = sex;
      // "quick" (the page's slider drags): no measured correction, so the body follows the
      // slider at interactive rates: the first-order preview once built, else one decode. The
      // measured labels shown are the drawn body's cheap ones (height, volume, weight; no girths).
      const bool quick = flag(body, "quick", false);
      if (quick) o.max_iterations = 1;
      // Quick requests are drawn from the preview once it is built ("preview": false asks for
      // the one decode, e.g. to compare).
      const auto preview = quick && flag(body, "preview", true) ? std::atomic_load(&preview_) : nullptr;
      MorphSummary summary;
      if (preview) {
        b.V = (*preview)(ShapePreview::first_change(model_->shape, cond, c0_));
        b.preview = true;
      } else {
        b.V = cond.empty() ? morpher_.decode(x0_) : morpher_.morph_encoding(x0_, cond, o, &summary, nullptr, &c0_);
        b.decodes = cond.empty() ? 1 : summary.decodes;
        b.last_decode = morpher_.decoder().last_timing();
      }
      b.decode_ms = ms_since(t0);
      const auto t1 = std::chrono::steady_clock::now();
      b.measured = quick ? measure_height_and_weight(b.V, model_->tmpl->faces()) : measure_morphed(morpher_, b.V, sex, cond);
      b.measure_ms = ms_since(t1);
    }
    b.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return b;
  }

  json to_json(const Body& b) const {
    std::vector<float> p;
    p.reserve(static_cast<size_t>(b.V.size()));
    for (int v = 0; v < b.V.rows(); ++v)
      for (int k = 0; k < 3; ++k) p.push_back(static_cast<float>(b.V(v, k)));
    json j = {{"positions", base64(p.data(), p.size() * 4)}, {"seconds", b.seconds}, {"preview", b.preview}};
    const DecodeTiming& t = b.last_decode;
    j["timing"] = {{"decodes", b.decodes},        {"morph_ms", b.decode_ms},
                   {"measure_ms", b.measure_ms},  {"last_decode_ms", t.total_ms},
                   {"assemble_ms", t.assemble_ms}, {"rotation_solve_ms", t.rotation_solve_ms},
                   {"rotation_path", t.rotation_path}, {"orthonormalise_ms", t.orthonormalise_ms},
                   {"poisson_ms", t.poisson_ms}, {"finish_ms", t.finish_ms}};
    for (auto& l : model_->shape.regression.labels)
      if (auto m = measured_label(l.name, b.measured); m && std::isfinite(*m)) j["measured"][l.name] = *m;
    return j;
  }

  std::string obj(const Body& b) const {
    std::string s = "# bodymodel serve\n";
    for (int v = 0; v < b.V.rows(); ++v) s += fmt::format("v {:.4f} {:.4f} {:.4f}\n", b.V(v, 0), b.V(v, 1), b.V(v, 2));
    const auto& F = model_->tmpl->faces();
    for (int i = 0; i < F.rows(); ++i) s += fmt::format("f {} {} {}\n", F(i, 0) + 1, F(i, 1) + 1, F(i, 2) + 1);
    return s;
  }

  // glTF binary (metres, as glTF requires; the skinning export's writer without a skin).
  std::string glb(const Body& b) const { return static_gltf_bytes(b.V, model_->tmpl->faces()); }

 private:
  static bool flag(const json& body, const char* name, bool fallback) {
    if (!body.contains(name)) return fallback;
    if (!body[name].is_boolean()) throw BadRequest(fmt::format("'{}' must be true or false", name));
    return body[name].get<bool>();
  }

  std::shared_ptr<const BodyModel> model_;
  ShapeMorpher morpher_;
  int max_decodes_;
  std::atomic<int> running_{0};
  const Eigen::VectorXd x0_, c0_;  // the mean body's encoding values and coefficients (once)
  std::shared_ptr<const ShapePreview> preview_;  // set once by preview_thread_ (atomic_load/store)
  std::atomic<bool> stop_{false};
  std::thread preview_thread_;
};

// Never throws: a message quoting a request's bytes that are not UTF-8 (a parse error's "last
// read") is written with U+FFFD, not thrown from here as a type_error into cpp-httplib.
void error_reply(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  res.set_content(json_text(json{{"error", message}}), "application/json");
}

// Whether the request announces a body (chunked, or a Content-Length other than 0).
bool has_body(const httplib::Request& req) {
  if (req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos) return true;
  const std::string n = req.get_header_value("Content-Length");
  return !n.empty() && n != "0";
}

// Reads the request body into `body`, at most `max_body` bytes however it is framed: cpp-httplib
// 0.11's payload limit checks a Content-Length only, and read a chunked body of any size into
// memory. Past the limit it stops reading and answers 413; false when it answered.
bool read_body(const httplib::Request& req, httplib::Response& res, const httplib::ContentReader& reader,
               size_t max_body, std::string& body) {
  auto refuse = [&](int status, const std::string& message) {
    error_reply(res, status, message);
    serve::t_close_connection = true;  // the unread rest of the body is not a next request
    return false;
  };
  if (req.is_multipart_form_data()) return refuse(415, "the request body must be JSON (application/json)");
  const bool chunked = req.get_header_value("Transfer-Encoding").find("chunked") != std::string::npos;
  if (!chunked) {
    const std::string length = req.get_header_value("Content-Length");
    if (length.empty()) return true;  // no body
    char* stop = nullptr;
    const unsigned long long n = std::strtoull(length.c_str(), &stop, 10);
    if (*stop != '\0' || length[0] == '-') return refuse(400, "bad Content-Length '" + length + "'");
    if (n > max_body)
      return refuse(413, fmt::format("request body of {} bytes is over --max-body ({} bytes)", n, max_body));
  }
  bool too_big = false;
  const bool complete = reader([&](const char* data, size_t n) {
    if (body.size() + n > max_body) {
      too_big = true;
      return false;
    }
    body.append(data, n);
    return true;
  });
  if (too_big) return refuse(413, fmt::format("request body over --max-body ({} bytes)", max_body));
  if (!complete) return refuse(400, "incomplete or malformed request body");
  return true;
}

// Reads the body (read_body), then runs f(parsed body), mapping failures to statuses: 400 bad
// JSON / bad values (the message the CLI prints), 503 when the decode cap is reached, 500
// otherwise.
template <class F>
void handle(const httplib::Request& req, httplib::Response& res, const httplib::ContentReader& reader,
            size_t max_body, F&& f) {
  std::string text;
  if (!read_body(req, res, reader, max_body, text)) return;
  try {
    json body = text.empty() ? json::object() : json::parse(text);
    if (!body.is_object()) throw BadRequest("the request body must be a JSON object");
    f(body);
  } catch (const json::exception& e) {
    error_reply(res, 400, std::string("bad JSON: ") + e.what());
  } catch (const BadRequest& e) {
    error_reply(res, 400, e.what());
  } catch (const InputError& e) {
    error_reply(res, 400, e.what());
  } catch (const std::overflow_error& e) {
    error_reply(res, 503, e.what());
  } catch (const std::exception& e) {
    error_reply(res, 500, e.what());
  }
}


httplib::Server* g_server = nullptr;
volatile std::sig_atomic_t g_stop_signal = 0;
void stop_server(int sig) {
  g_stop_signal = sig;
  if (g_server) g_server->stop();
}

// Returns the signal that stopped the server (0: it stopped otherwise).
// cpp-httplib compresses what the client accepts compressed; Debian's build has brotli, whose
// compression dominated the browser's round trip: API answers (base64 floats) go plain; the page
// and three.js at most gzip. A body sent anywhere but the POST routes is refused unread.
httplib::Server::HandlerResponse route_request(const httplib::Request& req, httplib::Response& res) {
  // A body sent anywhere but the POST routes is refused unread: cpp-httplib would read a
  // chunked one into memory whatever its size before answering 404.
  const bool api_post = req.method == "POST" &&
                        (req.path == "/api/body" || req.path == "/api/body.obj" || req.path == "/api/body.glb");
  if (!api_post && has_body(req) && req.method != "GET" && req.method != "HEAD") {
    error_reply(res, 404, fmt::format("no {} {} (the API: GET /api/model, POST /api/body[.obj|.glb])", req.method,
                                      req.path));
    serve::t_close_connection = true;
    return httplib::Server::HandlerResponse::Handled;
  }
  if (!api_post && has_body(req)) serve::t_close_connection = true;  // a GET's body is not read
  auto& r = const_cast<httplib::Request&>(req);  // the server's own, non-const request object
  const bool gzip = req.path.rfind("/api/", 0) != 0 &&
                    req.get_header_value("Accept-Encoding").find("gzip") != std::string::npos;
  r.headers.erase("Accept-Encoding");
  if (gzip) r.headers.emplace("Accept-Encoding", "gzip");
  return httplib::Server::HandlerResponse::Unhandled;
}

int serve_until_stopped(const ServeArgs& a) {
  auto model = std::make_shared<const BodyModel>(model_cli::load_model_for_cli(a.model));
  const fs::path three = a.three.empty() ? cli::default_three_js() : fs::path(a.three);
  if (three.empty() || !fs::is_regular_file(three))
    throw InputError("three.js not found at '" + three.string() +
                     "' (scripts/setup.sh installs it into the build folder; or give --three FILE / BODYMODEL_THREE)");
  const std::string three_js = read_text_file(three);
  auto service = std::make_shared<MorphService>(model, a.max_decodes, a.preview);
  const std::string describe = json_text(service->describe());

  serve::ConnectionLimits limits;
  limits.max_body = a.max_body;
  limits.request_timeout = std::chrono::seconds(a.timeout);
  limits.workers = a.threads;
  serve::GatedServer svr(limits);
  // Bodies reach the POST handlers below only, which read them through read_body; the payload
  // limit is a second guard for any other route cpp-httplib reads a Content-Length body for.
  svr.set_payload_max_length(a.max_body);
  svr.set_read_timeout(a.timeout, 0);
  svr.set_write_timeout(a.timeout, 0);
  // An exception that escapes a handler: without this, cpp-httplib answers 500 with the
  // exception's text in an EXCEPTION_WHAT header. Internal text stays inside the server.
  svr.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
    res.status = 500;
    res.set_content(R"({"error": "internal error"})", "application/json");
  });
  svr.set_pre_routing_handler(route_request);
  svr.Get("/", [](const httplib::Request&, httplib::Response& res) { res.set_content(cli::serve_html(), "text/html"); });
  svr.Get("/three.min.js", [&three_js](const httplib::Request&, httplib::Response& res) {
    res.set_content(three_js, "text/javascript");
  });
  svr.Get("/api/model", [&describe](const httplib::Request&, httplib::Response& res) {
    res.set_content(describe, "application/json");
  });
  const size_t max_body = a.max_body;
  svr.Post("/api/body", [service, max_body](const httplib::Request& req, httplib::Response& res,
                                            const httplib::ContentReader& reader) {
    handle(req, res, reader, max_body, [&](const json& body) {
      res.set_content(json_text(service->to_json(service->make(body))), "application/json");
    });
  });
  svr.Post("/api/body.obj", [service, max_body](const httplib::Request& req, httplib::Response& res,
                                                const httplib::ContentReader& reader) {
    handle(req, res, reader, max_body, [&](const json& body) {
      res.set_header("Content-Disposition", "attachment; filename=\"body.obj\"");
      res.set_content(service->obj(service->make(body)), "model/obj");
    });
  });
  svr.Post("/api/body.glb", [service, max_body](const httplib::Request& req, httplib::Response& res,
                                                const httplib::ContentReader& reader) {
    handle(req, res, reader, max_body, [&](const json& body) {
      res.set_header("Content-Disposition", "attachment; filename=\"body.glb\"");
      res.set_content(service->glb(service->make(body)), "model/gltf-binary");
    });
  });
  // cpp-httplib listens with a backlog of 5 (compiled into Debian's shared library): a burst of
  // connections beyond it has its SYNs dropped and the clients wait for retransmits (1, 3, 7,
  // 15, 31 s), which stalled 200 concurrent requests by up to a minute on a loaded machine.
  // Linux lets a second listen() on the bound socket raise the backlog.
  // Its default socket options set SO_REUSEPORT, with which a second server binds the same port
  // and the kernel splits the connections between the two: SO_REUSEADDR only (a restart may still
  // bind while old connections linger in TIME_WAIT), so a busy port is refused.
  int listen_fd = -1;
  svr.set_socket_options([&listen_fd](socket_t sock) {
    int yes = 1;
    ::setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    listen_fd = sock;
  });
  if (!svr.bind_to_port(a.host, a.port))
    throw InputError(fmt::format("cannot listen on {}:{} (in use, or not an address of this machine)", a.host, a.port));
  if (listen_fd >= 0) ::listen(listen_fd, SOMAXCONN);
  if (a.host != "127.0.0.1" && a.host != "localhost" && a.host != "::1")
    cli::warn("serving on " + a.host + ": reachable from other machines (no authentication)");
  g_server = &svr;
  std::signal(SIGINT, stop_server);
  std::signal(SIGTERM, stop_server);
  fmt::print("serving {} on http://{}:{}/ (Ctrl-C stops)\n", a.model, a.host, a.port);
  std::fflush(stdout);
  svr.listen_after_bind();
  g_server = nullptr;
  svr.shut_down();  // before the handlers' captures go
  return g_stop_signal;
}

void run_serve(const ServeArgs& a) {
  // Stopped by a signal: ends as the other verbs do on one (130 after Ctrl-C, 143 after
  // SIGTERM; tools/main.cc), once the server and the model are released.
  if (const int sig = serve_until_stopped(a)) {
    std::signal(sig, SIG_DFL);
    std::raise(sig);
  }
}

}  // namespace

BODYMODEL_VERB(add_serve_verb) {
  auto a = std::make_shared<ServeArgs>();
  auto* cmd = app.add_subcommand(
      "serve",
      "Live morphing in the browser: serves a page with a slider per label of the model, a seed box\n"
      "for generate, the measured labels and OBJ / glb downloads, and its JSON API:\n"
      "  GET /api/model         labels (name, unit, min, max, mean) and the faces\n"
      "  POST /api/body         {\"labels\": {LABEL: VALUE, ...}} morphs the mean body, {\"seed\": N, ...}\n"
      "                         generates one, \"quick\": true = no measured correction: the\n"
      "                         first-order preview once built (\"preview\": false = one decode);\n"
      "                         answers positions (base64 float32), the measured labels, timing\n"
      "  POST /api/body.obj     the same body as an OBJ file (mm)\n"
      "  POST /api/body.glb     the same body as a glTF binary (metres)\n"
      "Bad JSON or values far outside the data: 400 with the message. Loopback unless --host.");
  cmd->add_option("model", a->model, "Model (.npz from `bodymodel build`)")->required();
  cmd->add_option("--port", a->port, "TCP port")->capture_default_str()->check(CLI::Range(1, 65535));
  cmd->add_option("--host", a->host, "Address to listen on (127.0.0.1: this machine only)")->capture_default_str();
  cmd->add_option("--max-decodes", a->max_decodes, "Morphs run at once; more get 503")
      ->capture_default_str()->check(CLI::Range(1, 64));
  cmd->add_option("--threads", a->threads, "Connection threads")->capture_default_str()->check(CLI::Range(1, 256));
  cmd->add_option("--max-body", a->max_body, "Largest request body (bytes); larger get 413")
      ->capture_default_str()->check(CLI::Range(size_t{64}, size_t{1} << 20));
  cmd->add_option("--timeout", a->timeout,
                  "A request (headers and body) must arrive within this of its first byte, an answer be\n"
                  "written within it, and an idle connection is closed after it (s)")
      ->capture_default_str()->check(CLI::Range(1, 600));
  cmd->add_flag("!--no-preview", a->preview,
                "Decode every slider move (default: after a start-up of 2 decodes per model component, drags are\n"
                "drawn from a first-order preview, and decoded exactly when the slider is released)");
  cmd->add_option("--three", a->three, "three.min.js to serve (default: the build folder's npm install)");
  cmd->callback([a] { run_serve(*a); });
}

}  // namespace bodymodel
