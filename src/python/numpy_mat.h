#pragma once
// numpy arrays <-> cv::Mat for dynaorb._core's bindings.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "dynaorb/io/errors.h"

namespace dynaorb {

namespace py = pybind11;

// Wraps a C-contiguous numpy array as a cv::Mat without copying (the array
// must outlive the Mat); other arrays are copied.
inline cv::Mat as_mat(const py::object& obj, const char* what) {
  if (obj.is_none()) return cv::Mat();
  auto arr = py::array::ensure(obj, py::array::c_style);
  if (!arr) throw InputError(std::string(what) + ": expected a numpy array");
  int depth;
  const py::dtype dt = arr.dtype();
  if (dt.is(py::dtype::of<uint8_t>())) depth = CV_8U;
  else if (dt.is(py::dtype::of<uint16_t>())) depth = CV_16U;
  else if (dt.is(py::dtype::of<float>())) depth = CV_32F;
  else if (dt.is(py::dtype::of<int32_t>())) depth = CV_32S;
  else throw InputError(std::string(what) + ": dtype " + py::str(dt.attr("name")).cast<std::string>() + " is not supported");
  if (arr.ndim() != 2 && arr.ndim() != 3) throw InputError(std::string(what) + ": expected a 2-D or 3-D array");
  const int channels = arr.ndim() == 3 ? static_cast<int>(arr.shape(2)) : 1;
  if (channels < 1 || channels > 4) throw InputError(std::string(what) + ": expected 1 to 4 channels");
  const cv::Mat m(static_cast<int>(arr.shape(0)), static_cast<int>(arr.shape(1)), CV_MAKETYPE(depth, channels),
                  const_cast<void*>(arr.data()));
  // A non-contiguous array (a slice) was copied into arr, which dies here: the Mat gets its own copy.
  return arr.ptr() == obj.ptr() ? m : m.clone();
}

inline py::object to_numpy(const cv::Mat& m) {
  if (m.empty()) return py::none();
  cv::Mat c = m.isContinuous() ? m : m.clone();
  std::vector<py::ssize_t> shape = {c.rows, c.cols};
  if (c.channels() > 1) shape.push_back(c.channels());
  switch (c.depth()) {
    case CV_8U: return py::array_t<uint8_t>(shape, c.ptr<uint8_t>());
    case CV_16U: return py::array_t<uint16_t>(shape, c.ptr<uint16_t>());
    case CV_32F: return py::array_t<float>(shape, c.ptr<float>());
    case CV_64F: return py::array_t<double>(shape, c.ptr<double>());
    default: throw std::runtime_error("unsupported cv::Mat depth");
  }
}

}  // namespace dynaorb
