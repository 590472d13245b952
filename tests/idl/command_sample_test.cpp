// The command decoder (idl/command_sample.hpp): each field of a fiberfem::Command
// sample checked, the refusal naming the field. Samples built as DDS delivers them (C
// strings, a missing one a null pointer).

#include "idl/command_sample.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace fiberfem::dds {
namespace {

struct Fields {
  std::string run_id = "run", command_id = "c1", client_id = "me", kind = "pause", args = "{}";
};

DecodedCommand decode(Fields f, bool null_args = false) {
  fiberfem_Command c{};
  c.run_id = f.run_id.data();
  c.command_id = f.command_id.data();
  c.client_id = f.client_id.data();
  c.kind = f.kind.data();
  c.args = null_args ? nullptr : f.args.data();
  return decode_command(c);
}

TEST(CommandSample, AGoodSampleDecodesToItsFields) {
  Fields f;
  f.args = "{\"gravity\": [0, 0, -9.81],\n\t\"note\": \"h\xc3\xa9\"}";  // line breaks, tabs and UTF-8 allowed
  const DecodedCommand d = decode(f);
  EXPECT_EQ(d.run_id, "run");
  EXPECT_EQ(d.command_id, "c1");
  EXPECT_EQ(d.client_id, "me");
  EXPECT_EQ(d.kind, "pause");
  EXPECT_EQ(d.args, f.args);
  EXPECT_EQ(decode(Fields{}, /*null_args=*/true).args, "");  // a missing field is empty
}

TEST(CommandSample, EachBadFieldIsRefusedByName) {
  struct Case {
    Fields f;
    std::vector<std::string> expect;
  };
  const auto with = [](auto set) {
    Fields f;
    set(f);
    return f;
  };
  const std::vector<Case> cases = {
      {with([](Fields& f) { f.command_id = ""; }), {"'command_id' is empty"}},
      {with([](Fields& f) { f.kind = ""; }), {"'kind' is empty"}},
      {with([](Fields& f) { f.kind = "set material"; }), {"'kind'", "not a command name"}},
      {with([](Fields& f) { f.kind = std::string(65, 'k'); }), {"'kind' is 65 bytes", "limit is 64"}},
      {with([](Fields& f) { f.run_id = std::string(257, 'r'); }), {"'run_id' is 257 bytes", "limit is 256"}},
      {with([](Fields& f) { f.command_id = std::string(300, 'c'); }), {"'command_id' is 300 bytes"}},
      {with([](Fields& f) { f.client_id = "me\x01"; }), {"'client_id'", "control character (byte 1 at offset 2)"}},
      {with([](Fields& f) { f.command_id = "c\n1"; }), {"'command_id'", "control character"}},
      {with([](Fields& f) { f.args = "{\"a\": \x7f}"; }), {"'args'", "control character (byte 127"}},
      {with([](Fields& f) { f.args = std::string(kMaxCommandArgsBytes + 1, ' '); }), {"'args' is 1048577 bytes", "limit is 1048576"}},
      {with([](Fields& f) { f.args = "{\"a\": \"\xff\"}"; }), {"'args' is not valid UTF-8 (at byte offset 7)"}},
      {with([](Fields& f) { f.args = "\xc0\xaf"; }), {"'args' is not valid UTF-8"}},          // overlong '/'
      {with([](Fields& f) { f.args = "\xed\xa0\x80"; }), {"'args' is not valid UTF-8"}},      // a UTF-16 surrogate
      {with([](Fields& f) { f.args = "\xf4\x90\x80\x80"; }), {"'args' is not valid UTF-8"}},  // above U+10FFFF
      {with([](Fields& f) { f.args = "\xe2\x82"; }), {"'args' is not valid UTF-8"}},          // cut short
  };
  for (const Case& c : cases) {
    try {
      decode(c.f);
      ADD_FAILURE() << "accepted: " << c.expect.front();
    } catch (const CommandSampleError& e) {
      for (const std::string& x : c.expect) EXPECT_NE(std::string(e.what()).find(x), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace fiberfem::dds
