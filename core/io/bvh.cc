#include "core/io/bvh.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "core/error.h"
#include "core/io/atomic_write.h"

namespace bodymodel {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

struct Token {
  std::string_view text;
  int line;
};

// Whitespace-separated tokens of the HIERARCHY part, with line numbers.
class Lexer {
 public:
  Lexer(std::string_view text, const std::string& source) : text_(text), source_(source) {}

  // Next token, or an empty token (line = current) at the end of the text.
  Token next() {
    skip_space();
    if (pos_ >= text_.size()) return {{}, line_};
    const size_t start = pos_;
    while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
    return {text_.substr(start, pos_ - start), line_};
  }
  Token peek() {
    const size_t p = pos_;
    const int l = line_;
    Token t = next();
    pos_ = p;
    line_ = l;
    return t;
  }
  [[noreturn]] void fail(int line, const std::string& what) const {
    throw InputError("BVH '" + source_ + "' line " + std::to_string(line) + ": " + what);
  }
  Token expect(std::string_view word, std::string_view context) {
    Token t = next();
    if (t.text != word)
      fail(t.line, "expected '" + std::string(word) + "' " + std::string(context) + ", found " +
                       describe(t));
    return t;
  }
  double number(std::string_view what) {
    Token t = next();
    const std::string s(t.text);
    char* end = nullptr;
    errno = 0;
    const double v = s.empty() ? 0.0 : std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() || errno == ERANGE || !std::isfinite(v))
      fail(t.line, "expected a number (" + std::string(what) + "), found " + describe(t));
    return v;
  }
  static std::string describe(const Token& t) {
    return t.text.empty() ? "the end of the file" : "'" + std::string(t.text) + "'";
  }
  // Position just after the current line (for the MOTION block).
  size_t position() const { return pos_; }
  int line() const { return line_; }
  void skip_to_end_of_line() {
    while (pos_ < text_.size() && text_[pos_] != '\n') ++pos_;
  }

 private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }
  void skip_space() {
    while (pos_ < text_.size() && is_space(text_[pos_])) {
      if (text_[pos_] == '\n') ++line_;
      ++pos_;
    }
  }
  std::string_view text_;
  const std::string& source_;
  size_t pos_ = 0;
  int line_ = 1;
};

bool parse_channel(std::string_view s, BvhChannel* c) {
  static constexpr std::array<std::string_view, 6> names{
      "Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"};
  for (int i = 0; i < 6; ++i)
    if (s == names[i]) {
      *c = static_cast<BvhChannel>(i);
      return true;
    }
  return false;
}

// Joints nested deeper than this are refused: the parser (and the writer) recurse once per level,
// and a hostile file nesting 20 000 joints overflowed the stack (SIGSEGV). Real skeletons nest a
// few tens of levels (MakeHuman's default skeleton: 17, fingers included).
constexpr int kMaxJointDepth = 256;

void parse_joint(Lexer& lex, BvhMotion& m, int parent, int& channel_count, int depth = 0) {
  Token name = lex.next();
  if (depth >= kMaxJointDepth)
    lex.fail(name.line, "joints are nested more than " + std::to_string(kMaxJointDepth) +
                            " levels deep (at '" + std::string(name.text.substr(0, 40)) +
                            "'); not a skeleton");
  if (name.text.empty() || name.text == "{") lex.fail(name.line, "expected a joint name, found " +
                                                                     Lexer::describe(name));
  BvhJoint j;
  j.name = std::string(name.text);
  j.parent = parent;
  lex.expect("{", "after joint '" + j.name + "'");
  lex.expect("OFFSET", "in joint '" + j.name + "'");
  for (int k = 0; k < 3; ++k) j.offset[k] = lex.number("OFFSET of joint '" + j.name + "'");
  Token t = lex.peek();
  if (t.text == "CHANNELS") {
    lex.next();
    const double n = lex.number("channel count of joint '" + j.name + "'");
    if (n < 0 || n > 6 || n != std::floor(n))
      lex.fail(t.line, "joint '" + j.name + "': channel count must be 0..6, found " +
                           std::to_string(n));
    for (int k = 0; k < static_cast<int>(n); ++k) {
      Token c = lex.next();
      BvhChannel ch;
      if (!parse_channel(c.text, &ch))
        lex.fail(c.line, "joint '" + j.name + "' declares " + std::to_string(int(n)) +
                             " channels but channel " + std::to_string(k + 1) + " is " +
                             Lexer::describe(c) + " (expected Xposition..Zrotation)");
      for (BvhChannel prev : j.channels)
        if (prev == ch)
          lex.fail(c.line, "joint '" + j.name + "' lists channel " + std::string(c.text) +
                               " twice");
      j.channels.push_back(ch);
    }
  }
  j.first_channel = channel_count;
  channel_count += static_cast<int>(j.channels.size());
  const int self = static_cast<int>(m.joints.size());
  m.joints.push_back(std::move(j));
  for (;;) {
    Token k = lex.next();
    if (k.text == "}") return;
    if (k.text == "JOINT") {
      parse_joint(lex, m, self, channel_count, depth + 1);
    } else if (k.text == "End") {
      lex.expect("Site", "after 'End'");
      lex.expect("{", "after 'End Site'");
      lex.expect("OFFSET", "in an End Site");
      Eigen::Vector3d e;
      for (int i = 0; i < 3; ++i) e[i] = lex.number("End Site OFFSET");
      lex.expect("}", "closing an End Site");
      m.joints[self].end_site = e;
    } else {
      lex.fail(k.line, "expected JOINT, End Site or '}' in joint '" + m.joints[self].name +
                           "', found " + Lexer::describe(k));
    }
  }
}

}  // namespace

std::string_view bvh_channel_name(BvhChannel c) {
  static constexpr std::array<std::string_view, 6> names{
      "Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation"};
  return names[static_cast<int>(c)];
}

int BvhMotion::channel_count() const {
  int n = 0;
  for (const auto& j : joints) n += static_cast<int>(j.channels.size());
  return n;
}

int BvhMotion::find(std::string_view name) const {
  for (int i = 0; i < static_cast<int>(joints.size()); ++i)
    if (joints[i].name == name) return i;
  return -1;
}

Eigen::MatrixX3d BvhMotion::rest_positions() const {
  Eigen::MatrixX3d P(joints.size(), 3);
  for (size_t i = 0; i < joints.size(); ++i) {
    const auto& j = joints[i];
    P.row(i) = j.offset.transpose();
    if (j.parent >= 0) P.row(i) += P.row(j.parent);
  }
  return P;
}

void BvhMotion::validate() const {
  int col = 0;
  for (size_t i = 0; i < joints.size(); ++i) {
    const auto& j = joints[i];
    if (j.parent < -1 || j.parent >= static_cast<int>(i))
      throw InputError("BVH joint '" + j.name + "': parent index " + std::to_string(j.parent) +
                       " is not an earlier joint");
    if (j.first_channel != col)
      throw InputError("BVH joint '" + j.name + "': first channel column " +
                       std::to_string(j.first_channel) + ", expected " + std::to_string(col));
    col += static_cast<int>(j.channels.size());
  }
  if (joints.empty()) throw InputError("BVH motion has no joints");
  if (frames.cols() != col)
    throw InputError("BVH motion: frames have " + std::to_string(frames.cols()) +
                     " values but the joints declare " + std::to_string(col) + " channels");
  if (!(frame_time > 0)) throw InputError("BVH motion: frame time must be positive");
}

BvhMotion parse_bvh(std::string_view text, const std::string& source) {
  Lexer lex(text, source);
  BvhMotion m;
  m.source = source;
  lex.expect("HIERARCHY", "at the start of the file");
  int channel_count = 0;
  Token t = lex.next();
  if (t.text != "ROOT") lex.fail(t.line, "expected ROOT, found " + Lexer::describe(t));
  parse_joint(lex, m, -1, channel_count);
  for (t = lex.next(); t.text == "ROOT"; t = lex.next()) parse_joint(lex, m, -1, channel_count);
  if (t.text != "MOTION")
    lex.fail(t.line, "expected MOTION after the hierarchy, found " + Lexer::describe(t));
  Token f = lex.next();
  if (f.text != "Frames:") lex.fail(f.line, "expected 'Frames:', found " + Lexer::describe(f));
  const double nf = lex.number("frame count");
  if (nf < 0 || nf != std::floor(nf) || nf > 1e8)
    lex.fail(f.line, "frame count must be a non-negative integer, found " + std::to_string(nf));
  Token ft = lex.next();
  if (ft.text != "Frame") lex.fail(ft.line, "expected 'Frame Time:', found " + Lexer::describe(ft));
  lex.expect("Time:", "after 'Frame'");
  m.frame_time = lex.number("frame time");
  if (!(m.frame_time > 0)) lex.fail(ft.line, "frame time must be positive");
  lex.skip_to_end_of_line();

  // Frame lines: one per frame, exactly channel_count numbers each.
  const int frames = static_cast<int>(nf);
  m.frames.resize(frames, channel_count);
  size_t pos = lex.position();
  int line = lex.line();
  const std::string body(text.substr(std::min(pos, text.size())));
  const char* p = body.c_str();
  const char* end = p + body.size();
  int frame = 0;
  while (p < end && frame <= frames) {
    const char* eol = static_cast<const char*>(std::memchr(p, '\n', end - p));
    if (!eol) eol = end;
    const char* q = p;
    while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r' || *q == '\n')) ++q;
    if (q < eol) {
      if (frame == frames)
        lex.fail(line, "more frame lines than the " + std::to_string(frames) +
                           " announced by 'Frames:'");
      int k = 0;
      for (;;) {
        while (q < eol && (*q == ' ' || *q == '\t' || *q == '\r')) ++q;
        if (q >= eol) break;
        char* next;
        const double v = std::strtod(q, &next);
        if (next == q || (next < eol && !(*next == ' ' || *next == '\t' || *next == '\r')))
          lex.fail(line, "frame " + std::to_string(frame) + ": value " + std::to_string(k + 1) +
                             " is not a number ('" +
                             std::string(q, std::min<const char*>(eol, q + 20)) + "')");
        if (!std::isfinite(v))
          lex.fail(line, "frame " + std::to_string(frame) + ": value " + std::to_string(k + 1) +
                             " is not finite");
        if (k < channel_count) m.frames(frame, k) = v;
        ++k;
        q = next;
      }
      if (k != channel_count)
        lex.fail(line, "frame " + std::to_string(frame) + " has " + std::to_string(k) +
                           " values, expected " + std::to_string(channel_count) +
                           " (the CHANNELS of the hierarchy)");
      ++frame;
    }
    p = eol + 1;
    ++line;
  }
  if (frame != frames)
    lex.fail(line - 1, "the file ends after " + std::to_string(frame) + " frames, but 'Frames:' "
                       "announced " + std::to_string(frames) + " (truncated file?)");
  return m;
}

BvhMotion read_bvh(const std::filesystem::path& path) {
  return parse_bvh(read_text_file(path), path.string());
}

namespace {
void format_joint(const BvhMotion& m, int j, int depth, std::string& out) {
  const auto& jt = m.joints[j];
  const std::string ind(depth, '\t');
  char buf[128];
  out += ind + (jt.parent < 0 ? "ROOT " : "JOINT ") + jt.name + "\n" + ind + "{\n";
  std::snprintf(buf, sizeof buf, "%s\tOFFSET %.6f %.6f %.6f\n", ind.c_str(), jt.offset[0],
                jt.offset[1], jt.offset[2]);
  out += buf;
  if (!jt.channels.empty()) {
    out += ind + "\tCHANNELS " + std::to_string(jt.channels.size());
    for (BvhChannel c : jt.channels) out += " " + std::string(bvh_channel_name(c));
    out += "\n";
  }
  for (int c = j + 1; c < static_cast<int>(m.joints.size()); ++c)
    if (m.joints[c].parent == j) format_joint(m, c, depth + 1, out);
  if (jt.end_site) {
    std::snprintf(buf, sizeof buf, "%s\tEnd Site\n%s\t{\n%s\t\tOFFSET %.6f %.6f %.6f\n%s\t}\n",
                  ind.c_str(), ind.c_str(), ind.c_str(), (*jt.end_site)[0], (*jt.end_site)[1],
                  (*jt.end_site)[2], ind.c_str());
    out += buf;
  }
  out += ind + "}\n";
}
}  // namespace

std::string format_bvh(const BvhMotion& motion) {
  motion.validate();
  // Joints must be stored depth-first (as the reader produces them): the writer emits the
  // hierarchy depth-first and the frame columns in storage order.
  for (size_t j = 1; j < motion.joints.size(); ++j) {
    const int p = motion.joints[j].parent;
    // depth-first: the parent of j is j-1 or an ancestor of j-1
    int a = static_cast<int>(j) - 1;
    while (a >= 0 && a != p) a = motion.joints[a].parent;
    if (a != p)
      throw InputError("BVH output: joints are not stored in depth-first order ('" +
                       motion.joints[j].name + "')");
  }
  std::string out = "HIERARCHY\n";
  for (int j = 0; j < static_cast<int>(motion.joints.size()); ++j)
    if (motion.joints[j].parent < 0) format_joint(motion, j, 0, out);
  out += "MOTION\nFrames: " + std::to_string(motion.frame_count()) + "\n";
  char buf[64];
  std::snprintf(buf, sizeof buf, "Frame Time: %.8f\n", motion.frame_time);
  out += buf;
  for (int f = 0; f < motion.frame_count(); ++f) {
    for (int c = 0; c < motion.frames.cols(); ++c) {
      std::snprintf(buf, sizeof buf, c ? " %.6f" : "%.6f", motion.frames(f, c));
      out += buf;
    }
    out += "\n";
  }
  return out;
}

void write_bvh(const std::filesystem::path& path, const BvhMotion& motion) {
  std::string text;
  try {
    text = format_bvh(motion);
  } catch (const InputError& e) {
    throw InputError("cannot write BVH '" + path.string() + "': " + e.what());
  }
  write_text_file(path, text);
}

// ---- Euler angles --------------------------------------------------------------------------

Eigen::Matrix3d euler_to_rotation(const std::array<int, 3>& axes, const Eigen::Vector3d& degrees) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (int k = 0; k < 3; ++k)
    R = R * Eigen::AngleAxisd(degrees[k] * kDeg, Eigen::Vector3d::Unit(axes[k])).toRotationMatrix();
  return R;
}

Eigen::Vector3d rotation_to_euler(const Eigen::Matrix3d& R, const std::array<int, 3>& axes) {
  const int i = axes[0], j = axes[1], k = axes[2];
  if (i == j || j == k || i == k)
    throw InputError("rotation_to_euler: the three axes must be distinct");
  // Even permutations of (0,1,2) have s = +1. With R = R_i(a) R_j(b) R_k(c):
  // R(i,k) = s sin b, R(i,i) = cos b cos c, R(i,j) = −s cos b sin c, R(j,k) = −s sin a cos b,
  // R(k,k) = cos a cos b. b from atan2 (accurate near ±90°); a from the cos b-scaled entries;
  // c from what is left, R_j(b)ᵀ R_i(a)ᵀ R = R_k(c), so the three always reproduce R.
  const double s = ((j - i + 3) % 3 == 1) ? 1.0 : -1.0;
  const double cb = std::hypot(R(i, i), R(i, j));
  const double b = std::atan2(s * R(i, k), cb);
  const double a = cb > 1e-12 ? std::atan2(-s * R(j, k), R(k, k)) : 0.0;  // gimbal lock: a = 0
  const Eigen::Matrix3d M =
      (Eigen::AngleAxisd(a, Eigen::Vector3d::Unit(i)) * Eigen::AngleAxisd(b, Eigen::Vector3d::Unit(j)))
          .toRotationMatrix()
          .transpose() *
      R;
  const int u = (k + 1) % 3, w = (k + 2) % 3;
  const double c = std::atan2(M(w, u), M(u, u));
  return Eigen::Vector3d(a, b, c) / kDeg;
}

std::array<int, 3> bvh_rotation_order(const BvhJoint& joint) {
  std::array<int, 3> axes{};
  int n = 0;
  bool used[3] = {false, false, false};
  for (BvhChannel c : joint.channels)
    if (bvh_is_rotation(c) && n < 3) {
      axes[n++] = bvh_channel_axis(c);
      used[bvh_channel_axis(c)] = true;
    }
  for (int a = 0; a < 3 && n < 3; ++a)
    if (!used[a]) axes[n++] = a;
  return axes;
}

Eigen::Matrix3d bvh_joint_rotation(const BvhMotion& motion, int frame, int joint) {
  const BvhJoint& j = motion.joints.at(joint);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (size_t c = 0; c < j.channels.size(); ++c)
    if (bvh_is_rotation(j.channels[c])) {
      const double deg = motion.frames(frame, j.first_channel + static_cast<int>(c));
      R = R * Eigen::AngleAxisd(deg * kDeg, Eigen::Vector3d::Unit(bvh_channel_axis(j.channels[c])))
                  .toRotationMatrix();
    }
  return R;
}

Eigen::Vector3d bvh_root_position(const BvhMotion& motion, int frame) {
  const BvhJoint& root = motion.joints.at(0);
  Eigen::Vector3d p = root.offset;
  for (size_t c = 0; c < root.channels.size(); ++c)
    if (!bvh_is_rotation(root.channels[c]))
      p[bvh_channel_axis(root.channels[c])] =
          motion.frames(frame, root.first_channel + static_cast<int>(c));
  return p;
}

void set_bvh_joint_rotation(BvhMotion& motion, int frame, int joint, const Eigen::Matrix3d& R) {
  const BvhJoint& j = motion.joints.at(joint);
  std::array<int, 3> axes{};
  std::array<int, 3> cols{};
  int n = 0;
  for (size_t c = 0; c < j.channels.size(); ++c)
    if (bvh_is_rotation(j.channels[c]) && n < 3) {
      axes[n] = bvh_channel_axis(j.channels[c]);
      cols[n++] = j.first_channel + static_cast<int>(c);
    }
  if (n != 3)
    throw InputError("BVH joint '" + j.name + "' has " + std::to_string(n) +
                     " rotation channels; setting a rotation needs 3");
  const Eigen::Vector3d e = rotation_to_euler(R, axes);
  for (int k = 0; k < 3; ++k) motion.frames(frame, cols[k]) = e[k];
}

// ---- posing a skeleton ---------------------------------------------------------------------

BvhUpAxis guess_bvh_up_axis(const BvhMotion& motion) {
  const int knee = motion.find("lowerleg02.L");
  if (knee < 0) return BvhUpAxis::kY;
  for (size_t c = knee + 1; c < motion.joints.size(); ++c)
    if (motion.joints[c].parent == knee) {
      const Eigen::Vector3d& o = motion.joints[c].offset;
      return std::abs(o.z()) > std::abs(o.y()) ? BvhUpAxis::kZ : BvhUpAxis::kY;
    }
  if (motion.joints[knee].end_site) {
    const Eigen::Vector3d& o = *motion.joints[knee].end_site;
    return std::abs(o.z()) > std::abs(o.y()) ? BvhUpAxis::kZ : BvhUpAxis::kY;
  }
  return BvhUpAxis::kY;
}

Eigen::Matrix3d bvh_axis_conversion(BvhUpAxis up) {
  Eigen::Matrix3d C = Eigen::Matrix3d::Identity();
  if (up == BvhUpAxis::kZ) C << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // (x, y, z) → (x, z, −y)
  return C;
}

namespace {
// Length of the OFFSET of `name`'s first child joint (or End Site) in the file; 0 if none.
double bvh_bone_length(const BvhMotion& m, std::string_view name) {
  const int j = m.find(name);
  if (j < 0) return 0;
  for (size_t c = j + 1; c < m.joints.size(); ++c)
    if (m.joints[c].parent == j) return m.joints[c].offset.norm();
  return m.joints[j].end_site ? m.joints[j].end_site->norm() : 0.0;
}
}  // namespace

Pose bvh_frame_to_pose(const BvhMotion& motion, int frame, const Skeleton& skeleton,
                       const BvhPoseOptions& options) {
  if (frame < 0 || frame >= motion.frame_count())
    throw InputError("BVH frame " + std::to_string(frame) + " does not exist (the motion has " +
                     std::to_string(motion.frame_count()) + " frames)");
  const Eigen::Matrix3d C =
      bvh_axis_conversion(options.up_axis ? *options.up_axis : guess_bvh_up_axis(motion));
  Pose pose = Pose::rest(skeleton.bone_count());
  for (int j = 0; j < static_cast<int>(motion.joints.size()); ++j) {
    const int b = skeleton.find(motion.joints[j].name);
    if (b < 0) continue;
    pose.rotations[b] = C * bvh_joint_rotation(motion, frame, j) * C.transpose();
  }
  if (options.apply_root_translation) {
    double scale = 1;
    if (options.translation_scale) {
      scale = *options.translation_scale;
    } else {
      const int b = skeleton.find("upperleg02.L");
      const double file_len = bvh_bone_length(motion, "upperleg02.L");
      if (b >= 0 && file_len > 0)
        scale = (skeleton.tails.row(b) - skeleton.heads.row(b)).norm() / file_len;
    }
    bool has_position = false;
    for (BvhChannel c : motion.joints[0].channels) has_position |= !bvh_is_rotation(c);
    if (has_position) pose.root_translation = scale * (C * bvh_root_position(motion, frame));
  }
  return pose;
}

BvhMotion skeleton_poses_to_bvh(const Skeleton& skeleton, const std::vector<Pose>& poses,
                                double frame_time) {
  skeleton.validate();
  const int nb = skeleton.bone_count();
  // Depth-first order of the bones (the skeleton only guarantees parents first).
  std::vector<std::vector<int>> children(nb);
  std::vector<int> roots;
  for (int b = 0; b < nb; ++b)
    (skeleton.parents[b] < 0 ? roots : children[skeleton.parents[b]]).push_back(b);
  std::vector<int> order;
  std::vector<int> joint_of(nb, -1);
  std::vector<int> stack(roots.rbegin(), roots.rend());
  while (!stack.empty()) {
    const int b = stack.back();
    stack.pop_back();
    joint_of[b] = static_cast<int>(order.size());
    order.push_back(b);
    for (auto it = children[b].rbegin(); it != children[b].rend(); ++it) stack.push_back(*it);
  }
  BvhMotion m;
  m.frame_time = frame_time;
  int col = 0;
  for (int b : order) {
    BvhJoint j;
    j.name = skeleton.names[b];
    const int p = skeleton.parents[b];
    j.parent = p < 0 ? -1 : joint_of[p];
    j.offset = (skeleton.heads.row(b) - (p < 0 ? Eigen::RowVector3d::Zero().eval()
                                               : Eigen::RowVector3d(skeleton.heads.row(p))))
                   .transpose();
    if (p < 0)
      j.channels = {BvhChannel::kXposition, BvhChannel::kYposition, BvhChannel::kZposition};
    j.channels.insert(j.channels.end(),
                      {BvhChannel::kXrotation, BvhChannel::kYrotation, BvhChannel::kZrotation});
    j.first_channel = col;
    col += static_cast<int>(j.channels.size());
    if (children[b].empty())
      j.end_site = (skeleton.tails.row(b) - skeleton.heads.row(b)).transpose();
    m.joints.push_back(std::move(j));
  }
  m.frames.setZero(static_cast<Eigen::Index>(poses.size()), col);
  for (size_t f = 0; f < poses.size(); ++f) {
    const Pose& pose = poses[f];
    if (static_cast<int>(pose.rotations.size()) != nb)
      throw InputError("skeleton_poses_to_bvh: pose " + std::to_string(f) + " has " +
                       std::to_string(pose.rotations.size()) + " rotations for " +
                       std::to_string(nb) + " bones");
    for (int b = 0; b < nb; ++b) {
      const int j = joint_of[b];
      if (m.joints[j].parent < 0)
        for (int k = 0; k < 3; ++k)
          m.frames(f, m.joints[j].first_channel + k) = pose.root_translation[k];
      set_bvh_joint_rotation(m, static_cast<int>(f), j, pose.rotations[b]);
    }
  }
  return m;
}

}  // namespace bodymodel
