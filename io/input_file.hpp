#pragma once
/// @file The one check every reader runs on a path before opening it: exists, is a
/// regular file (not a directory, a FIFO or a device such as /dev/zero, which would never
/// end), and is readable.

#include <string>

namespace fiberfem::io {

/// What is wrong with reading `path` as an input file, or "" when nothing is: "it does
/// not exist", "it is a directory, not a file", "it is not a regular file (...)", "it
/// cannot be read (Permission denied)". Callers say "<path>: cannot open the X: <this>".
std::string input_file_problem(const std::string& path);

}  // namespace fiberfem::io
