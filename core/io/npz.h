// NumPy .npz archives (a zip of .npy arrays) that `np.load` opens: the format for models and
// rigs. Members are deflated (as np.savez_compressed writes them; stored when that would not
// shrink them); arrays little-endian, C order: float64 (or float32 where asked), integer arrays
// and scalars int32 ('<i4'), text as numpy unicode scalars. Reading accepts stored and deflated
// members, float64/float32 and (u)int8..64 arrays (files written before integers were int32 hold
// int64) and unicode/bytes strings.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace bodymodel {

// One array: shape plus data, either double or integer.
struct NpyArray {
  std::vector<int64_t> shape;
  std::vector<double> f64;     // used when is_float
  std::vector<int64_t> i64;    // used when !is_float (int32/int64/uint8 are widened)
  bool is_float = true;
  bool store_int64 = false;    // integer data written as '<i8' (read from an int64 array whose
                               // values do not all fit int32); otherwise '<i4'
  std::string text;            // for string arrays (dtype '<U' or '|S'): the one string
  bool store_float32 = false;  // float data written as '<f4' (≈ 7 significant digits, half the size)
  int store_int_bytes = 0;     // integer data written as '|i1' (1) or '<i2' (2); 0: int32/int64 as above
  bool store_uint8 = false;    // integer data written as '|u1' (packed bytes)
  std::string dtype;           // the numpy dtype it was read with ('<i4', '<f8', ...); "" when made here

  int64_t size() const;
};

class Npz {
 public:
  // Adders (C order: a matrix is stored row-major with shape [rows, cols]).
  void put(const std::string& name, const Eigen::MatrixXd& m);
  void put(const std::string& name, const Eigen::VectorXd& v);
  void put(const std::string& name, const Eigen::MatrixXi& m);
  void put(const std::string& name, const Eigen::VectorXi& v);
  void put(const std::string& name, double scalar);
  void put_int(const std::string& name, int scalar);                 // int32 scalar
  // The same stored as float32 ('<f4'): for large arrays whose precision needs ≈ 7 digits.
  void put_float32(const std::string& name, const Eigen::MatrixXd& m);
  void put_text(const std::string& name, const std::string& text);   // numpy '<U' scalar
  // Small integers stored as int8 ('|i1', bytes = 1) or int16 ('<i2', bytes = 2): quantised
  // arrays. Throws InputError if a value does not fit.
  void put_small_int(const std::string& name, const Eigen::MatrixXi& m, int bytes);
  // Raw bytes as a 1-D uint8 array ('|u1'): bit-packed codes.
  void put_bytes(const std::string& name, const std::vector<uint8_t>& bytes);

  // Accessors; throw InputError naming the file and the key if missing or of the wrong shape.
  bool has(const std::string& name) const;
  Eigen::MatrixXd matrix(const std::string& name) const;   // 2-D (1-D becomes a column)
  Eigen::VectorXd vector(const std::string& name) const;   // any shape, flattened
  Eigen::MatrixXi int_matrix(const std::string& name) const;
  Eigen::VectorXi int_vector(const std::string& name) const;
  double scalar(const std::string& name) const;
  std::string text(const std::string& name) const;
  std::vector<std::string> keys() const;

  const std::map<std::string, NpyArray>& arrays() const { return arrays_; }

  // Files (atomic write; strict read with errors naming the file and member).
  void save(const std::filesystem::path& path) const;
  static Npz load(const std::filesystem::path& path);
  // In-memory (for tests and fuzzing).
  std::string serialize() const;
  static Npz parse(const std::string& bytes, const std::string& what = "npz");

 private:
  std::map<std::string, NpyArray> arrays_;
  std::string source_ = "npz";
};

}  // namespace bodymodel
