#pragma once
// Errors shared by every clearfit module (see docs/conventions.md, "Failures").
//  - InputError: a user's file or option is wrong. Names the file, the element
//    (line, face, key, ...), what was expected, and what to do.
//  - std::invalid_argument / std::logic_error: a broken precondition inside
//    the program (a bug), with its location.
// Physical outcomes (a ray that misses, total internal reflection) are values,
// never exceptions. Library code never exits the process.
#include <stdexcept>
#include <string>

namespace clearfit {

class InputError : public std::runtime_error {
 public:
  /// @param file    the input it is about ("" when it is an option)
  /// @param element where in it: "line 12", "face 3", "key 'ior'", "header"
  /// @param problem what is wrong and what was expected
  /// @param hint    what the user can do (may be empty)
  InputError(std::string file, std::string element, std::string problem, std::string hint = {})
      : std::runtime_error(compose(file, element, problem, hint)),
        file_(std::move(file)),
        element_(std::move(element)),
        problem_(std::move(problem)),
        hint_(std::move(hint)) {}

  const std::string& file() const noexcept { return file_; }
  const std::string& element() const noexcept { return element_; }
  /// What is wrong and what was expected, without the file and element.
  const std::string& problem() const noexcept { return problem_; }
  /// What the user can do ("" when none was given).
  const std::string& hint() const noexcept { return hint_; }

 private:
  static std::string compose(const std::string& file, const std::string& element,
                             const std::string& problem, const std::string& hint) {
    std::string s;
    if (!file.empty()) s += file;
    if (!element.empty()) s += (s.empty() ? "" : ": ") + element;
    s += (s.empty() ? "" : ": ") + problem;
    if (!hint.empty()) s += " (" + hint + ")";
    return s;
  }
  std::string file_, element_, problem_, hint_;
};

/// An output that could not be written (no space, a file size limit, a folder that refuses it): always the run's
/// error (exit 2, as bad input: the user must act), never downgraded to a note or a warning as an optional
/// output's own problems are.
class OutputError : public InputError {
 public:
  using InputError::InputError;
};

}  // namespace clearfit
