// io/input_file.hpp: the path check every reader runs, and how file content is quoted in
// error messages (bytes a terminal would misread are escaped), seen through real readers.

#include "io/fiber_file.hpp"
#include "io/input_file.hpp"
#include "io/mesh_io.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

namespace fiberfem::io {
namespace {

TEST(InputFile, PrintableEscapesWhatATerminalWouldMisread) {
  EXPECT_EQ(printable("plain text 1.5e3 $Nodes"), "plain text 1.5e3 $Nodes");
  EXPECT_EQ(printable(std::string("a\x1b[2Jb", 6)), "a\\x1b[2Jb");  // an escape sequence clears no screen
  EXPECT_EQ(printable(std::string("\0\t\r\n\x7f", 5)), "\\x00\\x09\\x0d\\x0a\\x7f");
  EXPECT_EQ(printable("caf\xc3\xa9"), "caf\\xc3\\xa9");  // UTF-8 bytes too: no half characters
  EXPECT_EQ(printable(std::string(100, 'x'), 10), "xxxxxxxxxx...");
  EXPECT_EQ(printable("", 10), "");
}

std::string write_temp(const std::string& name, const std::string& content) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path, std::ios::binary) << content;
  return path;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error";
  return "";
}

TEST(InputFile, ReadersQuoteBadContentEscaped) {
  std::istringstream fibers("1 0 0\n1 \x1b[31m0\n");
  const std::string e1 = error_of([&] { read_fiber_vectors(fibers, "fibers.txt"); });
  EXPECT_NE(e1.find("\\x1b[31m"), std::string::npos) << e1;
  EXPECT_EQ(e1.find('\x1b'), std::string::npos) << "a raw escape byte reached the message";
  const std::string mesh = write_temp("bad.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n\x07\x08garbage\n");
  const std::string e2 = error_of([&] { read_mesh(mesh); });
  EXPECT_NE(e2.find("\\x07\\x08garbage"), std::string::npos) << e2;
  EXPECT_EQ(e2.find('\x07'), std::string::npos) << "a raw bell byte reached the message";
}

}  // namespace
}  // namespace fiberfem::io
