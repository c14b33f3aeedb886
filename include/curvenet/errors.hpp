#pragma once
/// \file errors.hpp
/// The exceptions the library throws. Inside the library every failed
/// precondition throws; the CLI turns the exception into one line on stderr
/// and a non-zero exit code.

#include <stdexcept>
#include <string>

namespace curvenet {

/// Base class of every curvenet exception.
class Error : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

/// A file could not be read, or breaks a rule of its format. `file()` names
/// the file and `element()` the element at fault: a vertex, a face, an edge,
/// or a JSON path such as `/profiles/3/from`.
class InputError : public Error {
public:
  InputError(std::string file, std::string element, const std::string& message);
  [[nodiscard]] const std::string& file() const { return file_; }
  [[nodiscard]] const std::string& element() const { return element_; }
  /// What is wrong, without the file and the element (to name them otherwise).
  [[nodiscard]] const std::string& reason() const { return reason_; }

private:
  std::string file_;
  std::string element_;
  std::string reason_;
};

/// An embedding stage could not place the net on the surface. The message
/// names the stage, the profile (or node), the sample, and the face or edge.
class EmbedError : public Error {
public:
  using Error::Error;
};

/// A topological invariant of the cut mesh is broken. This is a bug in
/// curvenet, never a property of the input.
class TopologyError : public Error {
public:
  using Error::Error;
};

} // namespace curvenet
