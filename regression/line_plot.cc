#include "regression/line_plot.h"

#define STB_IMAGE_WRITE_STATIC  // private copy: no clash with other users of stb
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {

namespace {

// 3×5 glyphs, rows top to bottom, 3 bits a row (bit 2 = left column).
const std::map<char, std::array<int, 5>>& font() {
  static const std::map<char, std::array<int, 5>> f = {
      {'0', {7, 5, 5, 5, 7}}, {'1', {2, 6, 2, 2, 7}}, {'2', {7, 1, 7, 4, 7}}, {'3', {7, 1, 3, 1, 7}},
      {'4', {5, 5, 7, 1, 1}}, {'5', {7, 4, 7, 1, 7}}, {'6', {7, 4, 7, 5, 7}}, {'7', {7, 1, 1, 1, 1}},
      {'8', {7, 5, 7, 5, 7}}, {'9', {7, 5, 7, 1, 7}}, {'.', {0, 0, 0, 0, 2}}, {'-', {0, 0, 7, 0, 0}},
      {':', {0, 2, 0, 2, 0}}, {'_', {0, 0, 0, 0, 7}}, {'%', {5, 1, 2, 4, 5}}, {' ', {0, 0, 0, 0, 0}},
      {'a', {2, 5, 7, 5, 5}}, {'b', {6, 5, 6, 5, 6}}, {'c', {7, 4, 4, 4, 7}}, {'d', {6, 5, 5, 5, 6}},
      {'e', {7, 4, 6, 4, 7}}, {'f', {7, 4, 6, 4, 4}}, {'g', {7, 4, 5, 5, 7}}, {'h', {5, 5, 7, 5, 5}},
      {'i', {7, 2, 2, 2, 7}}, {'j', {1, 1, 1, 5, 7}}, {'k', {5, 5, 6, 5, 5}}, {'l', {4, 4, 4, 4, 7}},
      {'m', {5, 7, 7, 5, 5}}, {'n', {6, 5, 5, 5, 5}}, {'o', {7, 5, 5, 5, 7}}, {'p', {7, 5, 7, 4, 4}},
      {'q', {7, 5, 5, 7, 1}}, {'r', {6, 5, 6, 5, 5}}, {'s', {7, 4, 7, 1, 7}}, {'t', {7, 2, 2, 2, 2}},
      {'u', {5, 5, 5, 5, 7}}, {'v', {5, 5, 5, 5, 2}}, {'w', {5, 5, 7, 7, 5}}, {'x', {5, 5, 2, 5, 5}},
      {'y', {5, 5, 2, 2, 2}}, {'z', {7, 1, 2, 4, 7}}, {'(', {1, 2, 2, 2, 1}}, {')', {4, 2, 2, 2, 4}},
      {'=', {0, 7, 0, 7, 0}}, {'/', {1, 1, 2, 4, 4}}};
  return f;
}

struct Canvas {
  int w, h;
  std::vector<unsigned char> rgb;
  Canvas(int w_, int h_) : w(w_), h(h_), rgb(static_cast<size_t>(w_) * h_ * 3, 255) {}
  void set(int x, int y, std::array<unsigned char, 3> c) {
    if (x < 0 || y < 0 || x >= w || y >= h) return;
    std::copy(c.begin(), c.end(), rgb.begin() + (static_cast<size_t>(y) * w + x) * 3);
  }
  void line(double x0, double y0, double x1, double y1, std::array<unsigned char, 3> c, int thick = 1) {
    const int steps = static_cast<int>(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
    for (int s = 0; s <= steps; ++s) {
      const double t = static_cast<double>(s) / steps;
      const int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
      const int y = static_cast<int>(std::lround(y0 + t * (y1 - y0)));
      for (int dx = 0; dx < thick; ++dx)
        for (int dy = 0; dy < thick; ++dy) set(x + dx, y + dy, c);
    }
  }
  void text(int x, int y, const std::string& s, std::array<unsigned char, 3> c, int scale = 2) {
    for (char ch : s) {
      const char key = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      auto it = font().find(key);
      if (it != font().end())
        for (int r = 0; r < 5; ++r)
          for (int col = 0; col < 3; ++col)
            if (it->second[r] & (4 >> col))
              for (int a = 0; a < scale; ++a)
                for (int b = 0; b < scale; ++b) set(x + col * scale + a, y + r * scale + b, c);
      x += 4 * scale;
    }
  }
};

std::string number(double v) {
  char buf[32];
  const double a = std::abs(v);
  std::snprintf(buf, sizeof buf, a >= 100 ? "%.0f" : a >= 10 ? "%.1f" : a >= 1 ? "%.2f" : "%.3f", v);
  return buf;
}

}  // namespace

void write_line_plot_png(const std::filesystem::path& path, const std::vector<LinePanel>& panels,
                         const LinePlotOptions& options) {
  if (panels.empty()) throw InputError("line plot '" + path.string() + "': no panels to draw");
  for (const auto& p : panels) {
    if (p.x.size() != p.y.size() || p.x.size() == 0)
      throw InputError("line plot '" + path.string() + "': panel '" + p.title + "' has " +
                       std::to_string(p.x.size()) + " x and " + std::to_string(p.y.size()) +
                       " y values (expected the same, at least one)");
    if (p.x2.size() != p.y2.size())
      throw InputError("line plot '" + path.string() + "': panel '" + p.title + "' has " +
                       std::to_string(p.x2.size()) + " x2 and " + std::to_string(p.y2.size()) + " y2 values");
    if (!p.x.allFinite() || !p.y.allFinite() || !p.x2.allFinite() || !p.y2.allFinite())
      throw InputError("line plot '" + path.string() + "': panel '" + p.title + "' has non-finite values");
  }
  const int W = options.width, PH = options.panel_height;
  Canvas c(W, PH * static_cast<int>(panels.size()) + 24);
  const std::array<unsigned char, 3> black{0, 0, 0}, grey{200, 200, 200}, blue{30, 90, 200}, red{220, 40, 40};
  const int left = 70, right = 30, top = 22, bottom = 28;
  for (size_t k = 0; k < panels.size(); ++k) {
    const LinePanel& p = panels[k];
    const int y0 = static_cast<int>(k) * PH;
    double xmin = p.x.minCoeff(), xmax = p.x.maxCoeff();
    double ymin = p.y.minCoeff(), ymax = p.y.maxCoeff();
    if (p.x2.size()) {
      xmin = std::min(xmin, p.x2.minCoeff()), xmax = std::max(xmax, p.x2.maxCoeff());
      ymin = std::min(ymin, p.y2.minCoeff()), ymax = std::max(ymax, p.y2.maxCoeff());
    }
    xmax = std::max(xmax, xmin + 1);
    if (ymax - ymin < 1e-12) ymax = ymin + 1;
    const double pad = 0.05 * (ymax - ymin);
    ymin = std::max(0.0, ymin - pad), ymax += pad;
    auto X = [&](double v) { return left + (v - xmin) / (xmax - xmin) * (W - left - right); };
    auto Y = [&](double v) { return y0 + top + (1 - (v - ymin) / (ymax - ymin)) * (PH - top - bottom); };
    c.text(left, y0 + 6, p.title, black);
    for (int t = 0; t <= 4; ++t) {  // horizontal grid with values
      const double v = ymin + t * (ymax - ymin) / 4;
      c.line(left, Y(v), W - right, Y(v), grey);
      c.text(4, static_cast<int>(Y(v)) - 5, number(v), black);
    }
    for (int t = 0; t <= 5; ++t) {  // x ticks
      const double v = xmin + t * (xmax - xmin) / 5;
      c.line(X(v), Y(ymin), X(v), Y(ymin) + 4, black);
      const std::string tick = std::to_string(static_cast<long>(std::lround(v)));
      c.text(static_cast<int>(X(v)) - 4 * static_cast<int>(tick.size()), static_cast<int>(Y(ymin)) + 7, tick, black);
    }
    c.line(left, Y(ymin), W - right, Y(ymin), black);
    c.line(left, Y(ymin), left, Y(ymax), black);
    for (Eigen::Index i = 1; i < p.x.size(); ++i)
      c.line(X(p.x(i - 1)), Y(p.y(i - 1)), X(p.x(i)), Y(p.y(i)), blue, 2);
    const std::array<unsigned char, 3> orange{240, 140, 20};
    for (Eigen::Index i = 1; i < p.x2.size(); ++i)
      c.line(X(p.x2(i - 1)), Y(p.y2(i - 1)), X(p.x2(i)), Y(p.y2(i)), orange, 2);
    Eigen::Index best = 0;
    p.y.minCoeff(&best);
    if (p.mark_minimum)
    for (int a = -3; a <= 3; ++a)
      for (int b = -3; b <= 3; ++b)
        if (a * a + b * b <= 9) c.set(static_cast<int>(X(p.x(best))) + a, static_cast<int>(Y(p.y(best))) + b, red);
  }
  c.text(W / 2 - 60, c.h - 16, options.x_label, black);
  int len = 0;
  unsigned char* png = stbi_write_png_to_mem(c.rgb.data(), W * 3, W, c.h, 3, &len);
  if (!png) throw InputError("line plot '" + path.string() + "': PNG encoding failed");
  const std::string bytes(reinterpret_cast<const char*>(png), static_cast<size_t>(len));
  STBIW_FREE(png);
  write_atomically(path, [&](std::ostream& os) { os.write(bytes.data(), static_cast<std::streamsize>(bytes.size())); });
}

}  // namespace bodymodel
