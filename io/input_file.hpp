#pragma once
/// @file The one check every reader runs on a path before opening it: exists, is a
/// regular file (not a directory, a FIFO or a device such as /dev/zero, which would never
/// end), and is readable.

#include <cstddef>
#include <string>

namespace fiberfem::io {

/// What is wrong with reading `path` as an input file, or "" when nothing is: "it does
/// not exist", "it is a directory, not a file", "it is not a regular file (...)", "it
/// cannot be read (Permission denied)". Callers say "<path>: cannot open the X: <this>".
std::string input_file_problem(const std::string& path);

/// `text` as it may be quoted in an error message: bytes that are not printable ASCII
/// (control characters, DEL, bytes >= 0x80 that a terminal would misread) written as \xNN,
/// and at most `max_bytes` of the input, "..." after a cut.
std::string printable(const std::string& text, size_t max_bytes = 80);

}  // namespace fiberfem::io
