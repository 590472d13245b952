#pragma once
/// @file The one HDF5 wrapper (STYLE.md habit 9): RAII handles around the HDF5 C API
/// (Debian 1.10) and the few operations the run archive needs. Every failure becomes an
/// h5::Error naming the file, dataset or attribute; HDF5's own error printing is off.

#include "io/input_file.hpp"

#include <hdf5.h>

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace fiberfem::archive::h5 {

/// An HDF5 call failed; the message names the object and the operation.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Turns HDF5's automatic error-stack printing off (once per process); the wrappers
/// report failures as exceptions instead.
inline void silence_errors() {
  static const bool done = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)done;
}

/// Throws Error(what) when `status` is negative.
inline void check(herr_t status, const std::string& what) {
  if (status < 0) throw Error("hdf5: " + what);
}

/// A move-only owner of an hid_t with its close function.
class Handle {
 public:
  using Closer = herr_t (*)(hid_t);
  Handle() = default;
  /// Takes ownership of `id`; throws Error(what) if it is invalid.
  Handle(hid_t id, Closer close, const std::string& what) : id_(id), close_(close) {
    if (id_ < 0) throw Error("hdf5: " + what);
  }
  Handle(Handle&& o) noexcept : id_(std::exchange(o.id_, -1)), close_(o.close_) {}
  Handle& operator=(Handle&& o) noexcept {
    if (this != &o) {
      reset();
      id_ = std::exchange(o.id_, -1);
      close_ = o.close_;
    }
    return *this;
  }
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  /// Closes now (no-op when empty).
  void reset() {
    if (id_ >= 0 && close_) close_(id_);
    id_ = -1;
  }
  hid_t id() const { return id_; }
  explicit operator bool() const { return id_ >= 0; }

 private:
  hid_t id_ = -1;
  Closer close_ = nullptr;
};

/// The HDF5 memory type of T (double, float, int32, int64, uint8, int8).
template <class T>
hid_t native_type() {
  if constexpr (std::is_same_v<T, double>) return H5T_NATIVE_DOUBLE;
  else if constexpr (std::is_same_v<T, float>) return H5T_NATIVE_FLOAT;
  else if constexpr (std::is_same_v<T, std::int32_t>) return H5T_NATIVE_INT32;
  else if constexpr (std::is_same_v<T, std::int64_t>) return H5T_NATIVE_INT64;
  else if constexpr (std::is_same_v<T, std::uint8_t>) return H5T_NATIVE_UINT8;
  else if constexpr (std::is_same_v<T, std::int8_t>) return H5T_NATIVE_INT8;
  else static_assert(!sizeof(T), "unsupported HDF5 element type");
}

using Dims = std::vector<hsize_t>;

/// A simple dataspace of `dims` (maxdims: H5S_UNLIMITED allowed; empty = dims).
inline Handle dataspace(const Dims& dims, const Dims& maxdims = {}) {
  return Handle(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), maxdims.empty() ? nullptr : maxdims.data()),
                H5Sclose, "cannot create a dataspace");
}

/// Property lists.
inline Handle property_list(hid_t cls, const std::string& what) { return Handle(H5Pcreate(cls), H5Pclose, what); }

/// File access with the latest format (SWMR needs it).
inline Handle latest_format_access() {
  Handle fapl = property_list(H5P_FILE_ACCESS, "cannot create a file access property list");
  check(H5Pset_libver_bounds(fapl.id(), H5F_LIBVER_LATEST, H5F_LIBVER_LATEST), "cannot ask for the latest file format");
  return fapl;
}

/// How a file is opened.
enum class Mode { read, read_swmr, write };

/// An open HDF5 file, remembering its path for messages.
class File {
 public:
  File() = default;
  /// Creates (truncating) a file with the latest format.
  static File create(const std::string& path) {
    silence_errors();
    Handle fapl = latest_format_access();
    File f;
    f.path_ = path;
    f.h_ = Handle(H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.id()), H5Fclose, "cannot create '" + path + "'");
    return f;
  }
  /// Opens an existing file.
  static File open(const std::string& path, Mode mode) {
    silence_errors();
    if (const std::string bad = io::input_file_problem(path); !bad.empty()) throw Error("cannot open '" + path + "': " + bad);
    if (H5Fis_hdf5(path.c_str()) <= 0) throw Error("'" + path + "' is not an HDF5 file (or cannot be read)");
    Handle fapl = latest_format_access();
    unsigned flags = mode == Mode::write ? H5F_ACC_RDWR : H5F_ACC_RDONLY;
    if (mode == Mode::read_swmr) flags |= H5F_ACC_SWMR_READ;
    File f;
    f.path_ = path;
    f.h_ = Handle(H5Fopen(path.c_str(), flags, fapl.id()), H5Fclose,
                  "cannot open '" + path + "'" +
                      (mode == Mode::read ? " (if a writer crashed, run `fiberfem archive recover` on it, or open it as a SWMR reader)" : ""));
    return f;
  }
  hid_t id() const { return h_.id(); }
  const std::string& path() const { return path_; }
  explicit operator bool() const { return static_cast<bool>(h_); }
  /// Starts single-writer/multiple-reader mode (every object must exist by now).
  void start_swmr_write() { check(H5Fstart_swmr_write(id()), "cannot start SWMR writing on '" + path_ + "'"); }
  /// Writes buffered data and metadata to the operating system (no fsync).
  void flush() { check(H5Fflush(id(), H5F_SCOPE_GLOBAL), "cannot flush '" + path_ + "'"); }
  void close() { h_.reset(); }

 private:
  Handle h_;
  std::string path_;
};

/// Whether `loc` has a link `name` (one level).
inline bool exists(hid_t loc, const std::string& name) { return H5Lexists(loc, name.c_str(), H5P_DEFAULT) > 0; }

inline Handle create_group(hid_t loc, const std::string& name) {
  return Handle(H5Gcreate2(loc, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), H5Gclose,
                "cannot create group '" + name + "'");
}
inline Handle open_group(hid_t loc, const std::string& name) {
  return Handle(H5Gopen2(loc, name.c_str(), H5P_DEFAULT), H5Gclose, "no group '" + name + "'");
}

/// A fixed-length string type of `n` bytes (at least 1).
inline Handle string_type(size_t n) {
  Handle t(H5Tcopy(H5T_C_S1), H5Tclose, "cannot copy the string type");
  check(H5Tset_size(t.id(), n == 0 ? 1 : n), "cannot size a string type");
  check(H5Tset_strpad(t.id(), H5T_STR_NULLTERM), "cannot pad a string type");
  return t;
}

/// Writes a scalar attribute (double, int64) or string attribute on `obj`.
template <class T>
void write_attribute(hid_t obj, const std::string& name, const T& value) {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose, "cannot create a scalar dataspace");
  if constexpr (std::is_convertible_v<T, std::string>) {
    const std::string s = value;
    Handle type = string_type(s.size() + 1);
    Handle a(H5Acreate2(obj, name.c_str(), type.id(), space.id(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
             "cannot create attribute '" + name + "'");
    check(H5Awrite(a.id(), type.id(), s.c_str()), "cannot write attribute '" + name + "'");
  } else {
    Handle a(H5Acreate2(obj, name.c_str(), native_type<T>(), space.id(), H5P_DEFAULT, H5P_DEFAULT), H5Aclose,
             "cannot create attribute '" + name + "'");
    check(H5Awrite(a.id(), native_type<T>(), &value), "cannot write attribute '" + name + "'");
  }
}

inline bool has_attribute(hid_t obj, const std::string& name) { return H5Aexists(obj, name.c_str()) > 0; }

/// Reads a string attribute (fixed or variable length).
inline std::string read_string_attribute(hid_t obj, const std::string& name) {
  Handle a(H5Aopen(obj, name.c_str(), H5P_DEFAULT), H5Aclose, "no attribute '" + name + "'");
  Handle ftype(H5Aget_type(a.id()), H5Tclose, "attribute '" + name + "' has no type");
  if (H5Tget_class(ftype.id()) != H5T_STRING) throw Error("hdf5: attribute '" + name + "' is not a string");
  if (H5Tis_variable_str(ftype.id()) > 0) {
    Handle mtype(H5Tcopy(H5T_C_S1), H5Tclose, "string type");
    H5Tset_size(mtype.id(), H5T_VARIABLE);
    char* p = nullptr;
    check(H5Aread(a.id(), mtype.id(), &p), "cannot read attribute '" + name + "'");
    std::string s = p ? p : "";
    H5free_memory(p);
    return s;
  }
  const size_t n = H5Tget_size(ftype.id());
  std::string s(n, '\0');
  Handle mtype = string_type(n);
  check(H5Aread(a.id(), mtype.id(), s.data()), "cannot read attribute '" + name + "'");
  s.resize(std::char_traits<char>::length(s.c_str()));
  return s;
}

/// Reads a numeric scalar attribute converted to T.
template <class T>
T read_attribute(hid_t obj, const std::string& name) {
  Handle a(H5Aopen(obj, name.c_str(), H5P_DEFAULT), H5Aclose, "no attribute '" + name + "'");
  T v{};
  check(H5Aread(a.id(), native_type<T>(), &v), "cannot read attribute '" + name + "'");
  return v;
}

/// A dataset, remembering its path for messages.
class Dataset {
 public:
  Dataset() = default;
  Dataset(Handle h, std::string path) : h_(std::move(h)), path_(std::move(path)) {}
  hid_t id() const { return h_.id(); }
  const std::string& path() const { return path_; }
  explicit operator bool() const { return static_cast<bool>(h_); }

  /// Current dimensions.
  Dims dims() const {
    Handle space(H5Dget_space(id()), H5Sclose, "no dataspace for '" + path_ + "'");
    const int rank = H5Sget_simple_extent_ndims(space.id());
    if (rank < 0) throw Error("hdf5: bad dataspace of '" + path_ + "'");
    Dims d(static_cast<size_t>(rank));
    H5Sget_simple_extent_dims(space.id(), d.data(), nullptr);
    return d;
  }
  /// Re-reads the dataset's metadata written by a SWMR writer since it was opened.
  void refresh() { check(H5Drefresh(id()), "cannot refresh '" + path_ + "'"); }

  /// Writes all of it.
  template <class T>
  void write_all(const T* data) {
    check(H5Dwrite(id(), native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "cannot write '" + path_ + "'");
  }
  /// Reads all of it (size from dims()).
  template <class T>
  std::vector<T> read_all() const {
    const Dims d = dims();
    size_t n = 1;
    for (hsize_t k : d) n *= k;
    std::vector<T> out(n);
    if (n > 0) check(H5Dread(id(), native_type<T>(), H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()), "cannot read '" + path_ + "'");
    return out;
  }

  /// Appends `rows` rows along dimension 0 (the other dimensions as created) from `data`
  /// (rows x row size elements). @return the new row count.
  template <class T>
  hsize_t append(const T* data, hsize_t rows) {
    Dims d = dims();
    const hsize_t at = d[0];
    d[0] += rows;
    check(H5Dset_extent(id(), d.data()), "cannot extend '" + path_ + "'");
    write_rows(data, at, rows);
    return d[0];
  }
  /// Adds `rows` rows along dimension 0 without writing them: they read as the fill value
  /// (0) and take no space until written (chunks are allocated when written).
  hsize_t extend(hsize_t rows) {
    Dims d = dims();
    d[0] += rows;
    check(H5Dset_extent(id(), d.data()), "cannot extend '" + path_ + "'");
    return d[0];
  }
  /// Writes rows [first, first + rows) (they must exist).
  template <class T>
  void write_rows(const T* data, hsize_t first, hsize_t rows) {
    Dims d = dims();
    Handle file_space(H5Dget_space(id()), H5Sclose, "no dataspace for '" + path_ + "'");
    Dims start(d.size(), 0), count = d;
    start[0] = first;
    count[0] = rows;
    check(H5Sselect_hyperslab(file_space.id(), H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr),
          "bad selection in '" + path_ + "'");
    Handle mem = dataspace(count);
    check(H5Dwrite(id(), native_type<T>(), mem.id(), file_space.id(), H5P_DEFAULT, data), "cannot write '" + path_ + "'");
  }
  /// Reads rows [first, first + rows) into a vector (rows x row size elements).
  template <class T>
  std::vector<T> read_rows(hsize_t first, hsize_t rows) const {
    const Dims d = dims();
    if (d.empty() || first + rows > d[0])
      throw Error("hdf5: rows " + std::to_string(first) + ".." + std::to_string(first + rows) + " beyond the " +
                  std::to_string(d.empty() ? 0 : d[0]) + " of '" + path_ + "'");
    Handle file_space(H5Dget_space(id()), H5Sclose, "no dataspace for '" + path_ + "'");
    Dims start(d.size(), 0), count = d;
    start[0] = first;
    count[0] = rows;
    size_t n = 1;
    for (hsize_t k : count) n *= k;
    std::vector<T> out(n);
    if (n == 0) return out;
    check(H5Sselect_hyperslab(file_space.id(), H5S_SELECT_SET, start.data(), nullptr, count.data(), nullptr),
          "bad selection in '" + path_ + "'");
    Handle mem = dataspace(count);
    check(H5Dread(id(), native_type<T>(), mem.id(), file_space.id(), H5P_DEFAULT, out.data()), "cannot read '" + path_ + "'");
    return out;
  }

 private:
  Handle h_;
  std::string path_;
};

/// Creates a fixed-size dataset of T with `dims` holding `data`.
template <class T>
Dataset create_fixed(hid_t loc, const std::string& name, const Dims& dims, const T* data) {
  Handle space = dataspace(dims);
  Dataset ds(Handle(H5Dcreate2(loc, name.c_str(), native_type<T>(), space.id(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                    H5Dclose, "cannot create dataset '" + name + "'"),
             name);
  size_t n = 1;
  for (hsize_t k : dims) n *= k;
  if (n > 0) ds.write_all(data);
  return ds;
}

/// Creates a dataset of T with zero rows, extendible along dimension 0 (unlimited), with
/// `row_dims` after it, chunked by `chunk_rows` rows; deflate level `compression` (0: none,
/// with the byte shuffle filter otherwise). `file_type` overrides the stored type (e.g.
/// float32 for double input); 0 stores T.
template <class T>
Dataset create_extendible(hid_t loc, const std::string& name, const Dims& row_dims, hsize_t chunk_rows, int compression,
                          hid_t file_type = 0) {
  Dims dims{0}, maxdims{H5S_UNLIMITED}, chunk{chunk_rows < 1 ? 1 : chunk_rows};
  for (hsize_t k : row_dims) {
    dims.push_back(k);
    maxdims.push_back(k);
    chunk.push_back(k < 1 ? 1 : k);
  }
  Handle space = dataspace(dims, maxdims);
  Handle dcpl = property_list(H5P_DATASET_CREATE, "cannot create a dataset property list");
  check(H5Pset_chunk(dcpl.id(), static_cast<int>(chunk.size()), chunk.data()), "cannot chunk '" + name + "'");
  const T zero{};
  check(H5Pset_fill_value(dcpl.id(), native_type<T>(), &zero), "cannot set the fill value of '" + name + "'");
  if (compression > 0) {
    check(H5Pset_shuffle(dcpl.id()), "cannot shuffle '" + name + "'");
    check(H5Pset_deflate(dcpl.id(), static_cast<unsigned>(compression)), "cannot compress '" + name + "'");
  }
  return Dataset(Handle(H5Dcreate2(loc, name.c_str(), file_type ? file_type : native_type<T>(), space.id(), H5P_DEFAULT,
                                   dcpl.id(), H5P_DEFAULT),
                        H5Dclose, "cannot create dataset '" + name + "'"),
                 name);
}

/// Opens a dataset; `where` names the file for the message.
inline Dataset open_dataset(hid_t loc, const std::string& name, const std::string& where) {
  return Dataset(Handle(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), H5Dclose, "no dataset '" + name + "' in " + where), name);
}

/// Writes a string as a 1-D uint8 dataset (any length, any bytes).
inline Dataset create_text(hid_t loc, const std::string& name, const std::string& text) {
  return create_fixed<std::uint8_t>(loc, name, {text.size()}, reinterpret_cast<const std::uint8_t*>(text.data()));
}
/// Reads a 1-D uint8 dataset as a string.
inline std::string read_text(const Dataset& ds) {
  const std::vector<std::uint8_t> b = ds.read_all<std::uint8_t>();
  return std::string(b.begin(), b.end());
}

}  // namespace fiberfem::archive::h5
