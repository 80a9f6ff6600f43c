#include "core/io/libigl_formats.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {
namespace {

std::string where(const std::filesystem::path& path, int line) {
  return path.string() + ":" + std::to_string(line);
}

std::vector<std::string> split_whitespace(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  std::string tok;
  while (in >> tok) out.push_back(tok);
  return out;
}

bool is_blank(const std::string& s) {
  for (char c : s)
    if (!std::isspace(static_cast<unsigned char>(c))) return false;
  return true;
}

double parse_double(const std::string& tok, const std::filesystem::path& path, int line,
                    const char* what) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(tok.c_str(), &end);
  if (end == tok.c_str() || *end != '\0')
    throw InputError(where(path, line) + ": expected a number for " + what + ", found '" + tok +
                     "'");
  if (!std::isfinite(v))
    throw InputError(where(path, line) + ": " + what + " is not finite ('" + tok + "')");
  return v;
}

long parse_int(const std::string& tok, const std::filesystem::path& path, int line,
               const char* what) {
  char* end = nullptr;
  const long v = std::strtol(tok.c_str(), &end, 10);
  if (end == tok.c_str() || *end != '\0')
    throw InputError(where(path, line) + ": expected an integer for " + what + ", found '" + tok +
                     "'");
  return v;
}

std::string read_all(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path.string() + ": cannot open file");
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TgfGraph read_tgf(const std::filesystem::path& path) {
  std::istringstream in(read_all(path));
  std::vector<Eigen::Vector3d> joints;
  std::vector<Eigen::Vector2i> edges;
  std::string line;
  int line_no = 0, section = 0;   // 0 joints, 1 edges, 2 done
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (is_blank(line)) continue;
    const auto tok = split_whitespace(line);
    if (tok[0] == "#") {
      ++section;
      continue;
    }
    if (section == 0) {
      if (tok.size() < 4)
        throw InputError(where(path, line_no) + ": expected a joint line '<index> <x> <y> <z>', "
                         "found " + std::to_string(tok.size()) + " fields");
      const long idx = parse_int(tok[0], path, line_no, "joint index");
      if (idx != static_cast<long>(joints.size()) + 1)
        throw InputError(where(path, line_no) + ": expected joint index " +
                         std::to_string(joints.size() + 1) + ", found " + tok[0]);
      joints.emplace_back(parse_double(tok[1], path, line_no, "joint x"),
                          parse_double(tok[2], path, line_no, "joint y"),
                          parse_double(tok[3], path, line_no, "joint z"));
    } else if (section == 1) {
      if (tok.size() < 2)
        throw InputError(where(path, line_no) + ": expected an edge line '<src> <dst>', found " +
                         std::to_string(tok.size()) + " field");
      const long a = parse_int(tok[0], path, line_no, "edge source");
      const long b = parse_int(tok[1], path, line_no, "edge destination");
      const long n = static_cast<long>(joints.size());
      if (a < 1 || a > n || b < 1 || b > n)
        throw InputError(where(path, line_no) + ": edge joint index out of range 1.." +
                         std::to_string(n) + ", found " + tok[0] + " " + tok[1]);
      if (a == b)
        throw InputError(where(path, line_no) + ": edge joins joint " + tok[0] + " to itself");
      edges.emplace_back(static_cast<int>(a - 1), static_cast<int>(b - 1));
    } else {
      throw InputError(where(path, line_no) + ": unexpected content after the edge section's "
                       "closing '#': '" + line + "'");
    }
  }
  if (section < 1 || joints.empty())
    throw InputError(path.string() + ": not a TGF skeleton (expected joint lines, then '#', then "
                     "edge lines), found " + std::to_string(joints.size()) + " joints and " +
                     std::to_string(section) + " '#' separators");
  TgfGraph g;
  g.C.resize(static_cast<Eigen::Index>(joints.size()), 3);
  for (size_t i = 0; i < joints.size(); ++i) g.C.row(static_cast<Eigen::Index>(i)) = joints[i];
  g.E.resize(static_cast<Eigen::Index>(edges.size()), 2);
  for (size_t i = 0; i < edges.size(); ++i) g.E.row(static_cast<Eigen::Index>(i)) = edges[i];
  return g;
}

Eigen::MatrixXd read_dmat(const std::filesystem::path& path) {
  const std::string bytes = read_all(path);
  size_t pos = 0;
  int line_no = 0;
  auto next_line = [&](std::string* out) -> bool {
    if (pos >= bytes.size()) return false;
    size_t e = bytes.find('\n', pos);
    if (e == std::string::npos) e = bytes.size();
    *out = bytes.substr(pos, e - pos);
    pos = std::min(bytes.size(), e + 1);
    ++line_no;
    return true;
  };
  std::string header;
  if (!next_line(&header)) throw InputError(path.string() + ": empty file, expected a DMAT header");
  auto header_tok = split_whitespace(header);
  if (header_tok.size() != 2)
    throw InputError(where(path, 1) + ": expected DMAT header '<ncols> <nrows>', found '" + header +
                     "'");
  long cols = parse_int(header_tok[0], path, 1, "column count");
  long rows = parse_int(header_tok[1], path, 1, "row count");
  if (cols < 0 || rows < 0)
    throw InputError(where(path, 1) + ": negative matrix size in DMAT header");
  if (cols == 0 && rows == 0) {
    // Binary: second line holds the real size, then raw little-endian doubles.
    std::string h2;
    if (!next_line(&h2))
      throw InputError(where(path, 2) + ": binary DMAT is missing its '<ncols> <nrows>' line");
    const auto t2 = split_whitespace(h2);
    if (t2.size() != 2)
      throw InputError(where(path, 2) + ": expected '<ncols> <nrows>' in binary DMAT, found '" +
                       h2 + "'");
    cols = parse_int(t2[0], path, 2, "column count");
    rows = parse_int(t2[1], path, 2, "row count");
    if (cols < 0 || rows < 0) throw InputError(where(path, 2) + ": negative matrix size");
    if (rows != 0 && cols > static_cast<long>(bytes.size() / 8) / rows)
      throw InputError(path.string() + ": binary DMAT of " + std::to_string(cols) + " columns × " +
                       std::to_string(rows) + " rows is larger than the file");
    const size_t expected = static_cast<size_t>(cols) * static_cast<size_t>(rows) * 8;
    if (bytes.size() - pos != expected)
      throw InputError(path.string() + ": binary DMAT of " + std::to_string(cols) + " columns × " +
                       std::to_string(rows) + " rows needs " + std::to_string(expected) +
                       " data bytes, found " + std::to_string(bytes.size() - pos));
    Eigen::MatrixXd M(rows, cols);   // column-major, like the file
    if (expected > 0) std::memcpy(M.data(), bytes.data() + pos, expected);  // empty: data() is null
    for (Eigen::Index i = 0; i < M.size(); ++i)
      if (!std::isfinite(M.data()[i]))
        throw InputError(path.string() + ": binary DMAT value at row " +
                         std::to_string(i % std::max<long>(rows, 1)) + ", column " +
                         std::to_string(i / std::max<long>(rows, 1)) + " is not finite");
    return M;
  }
  // Every ASCII value takes at least two bytes (digit and separator): a header promising more
  // than the file can hold is rejected before allocating (and before rows·cols can overflow).
  if (rows != 0 && cols > static_cast<long>(bytes.size() / 2 + 1) / rows)
    throw InputError(where(path, 1) + ": DMAT header promises " + std::to_string(cols) +
                     " columns × " + std::to_string(rows) + " rows, more values than the file holds");
  Eigen::MatrixXd M(rows, cols);
  const long total = rows * cols;
  long k = 0;
  std::string line;
  while (next_line(&line)) {
    for (const auto& tok : split_whitespace(line)) {
      if (k >= total)
        throw InputError(where(path, line_no) + ": more values than the header's " +
                         std::to_string(cols) + " × " + std::to_string(rows) + " = " +
                         std::to_string(total));
      M.data()[k++] = parse_double(tok, path, line_no, "matrix entry");
    }
  }
  if (k != total)
    throw InputError(path.string() + ": DMAT header promises " + std::to_string(total) +
                     " values (" + std::to_string(cols) + " columns × " + std::to_string(rows) +
                     " rows), found " + std::to_string(k));
  return M;
}

void write_dmat(const std::filesystem::path& path, const Eigen::MatrixXd& M, bool ascii) {
  write_atomically(path, [&](std::ostream& out) {
    if (ascii) {
      out << M.cols() << ' ' << M.rows() << '\n';
      out.precision(17);
      for (Eigen::Index c = 0; c < M.cols(); ++c)
        for (Eigen::Index r = 0; r < M.rows(); ++r) out << M(r, c) << '\n';
    } else {
      out << "0 0\n" << M.cols() << ' ' << M.rows() << '\n';
      out.write(reinterpret_cast<const char*>(M.data()),
                static_cast<std::streamsize>(M.size() * sizeof(double)));
    }
  });
}

BoneTransforms bone_transforms_from_stacked(const Eigen::MatrixXd& T, const std::string& what) {
  if (T.cols() != 3 || T.rows() % 4 != 0 || T.rows() == 0)
    throw InputError(what + ": expected stacked bone transforms of 4·#B rows by 3 columns, found " +
                     std::to_string(T.rows()) + " by " + std::to_string(T.cols()));
  const Eigen::Index B = T.rows() / 4;
  BoneTransforms M(static_cast<size_t>(B));
  for (Eigen::Index b = 0; b < B; ++b) {
    Eigen::Affine3d A = Eigen::Affine3d::Identity();
    A.linear() = T.block(4 * b, 0, 3, 3).transpose();
    A.translation() = T.row(4 * b + 3).transpose();
    if (!A.matrix().allFinite())
      throw InputError(what + ": bone " + std::to_string(b) + " transform is not finite");
    M[static_cast<size_t>(b)] = A;
  }
  return M;
}

Eigen::MatrixXd stacked_from_bone_transforms(const BoneTransforms& M) {
  Eigen::MatrixXd T(4 * static_cast<Eigen::Index>(M.size()), 3);
  for (size_t b = 0; b < M.size(); ++b) {
    const auto bi = static_cast<Eigen::Index>(b);
    T.block(4 * bi, 0, 3, 3) = M[b].linear().transpose();
    T.row(4 * bi + 3) = M[b].translation().transpose();
  }
  return T;
}

BoneTransforms read_tmat(const std::filesystem::path& path) {
  std::istringstream in(read_all(path));
  std::vector<Eigen::Vector3d> rows;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (is_blank(line)) continue;
    const auto tok = split_whitespace(line);
    if (tok.size() != 3)
      throw InputError(where(path, line_no) + ": expected 3 numbers per Tmat line, found " +
                       std::to_string(tok.size()));
    rows.emplace_back(parse_double(tok[0], path, line_no, "transform entry"),
                      parse_double(tok[1], path, line_no, "transform entry"),
                      parse_double(tok[2], path, line_no, "transform entry"));
  }
  if (rows.empty() || rows.size() % 4 != 0)
    throw InputError(path.string() + ": expected 4 lines per bone in a Tmat file, found " +
                     std::to_string(rows.size()) + " lines");
  Eigen::MatrixXd T(static_cast<Eigen::Index>(rows.size()), 3);
  for (size_t i = 0; i < rows.size(); ++i) T.row(static_cast<Eigen::Index>(i)) = rows[i];
  return bone_transforms_from_stacked(T, path.string());
}

std::vector<BoneTransforms> read_transform_animation(const std::filesystem::path& path) {
  const Eigen::MatrixXd A = read_dmat(path);
  if (A.rows() == 0 || A.rows() % 12 != 0)
    throw InputError(path.string() + ": expected a transform animation with 12·#B rows, found " +
                     std::to_string(A.rows()));
  const Eigen::Index B = A.rows() / 12;
  std::vector<BoneTransforms> frames;
  frames.reserve(static_cast<size_t>(A.cols()));
  for (Eigen::Index f = 0; f < A.cols(); ++f) {
    Eigen::MatrixXd T(4 * B, 3);
    for (Eigen::Index c = 0; c < 3; ++c) T.col(c) = A.col(f).segment(c * 4 * B, 4 * B);
    frames.push_back(
        bone_transforms_from_stacked(T, path.string() + " frame " + std::to_string(f)));
  }
  return frames;
}

}  // namespace bodymodel
