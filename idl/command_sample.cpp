#include "idl/command_sample.hpp"

#include <cctype>

namespace fiberfem::dds {
namespace {

// Length of the UTF-8 sequence starting at s[i] (RFC 3629: no overlongs, no surrogates,
// at most U+10FFFF), or 0 when it is not valid.
size_t utf8_length(const std::string& s, size_t i) {
  const auto b = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = b(i);
  if (c < 0x80) return 1;
  size_t n = 0;
  unsigned lo = 0x80, hi = 0xBF;
  if (c >= 0xC2 && c <= 0xDF) n = 2;
  else if (c == 0xE0) n = 3, lo = 0xA0;
  else if (c == 0xED) n = 3, hi = 0x9F;
  else if (c >= 0xE1 && c <= 0xEF) n = 3;
  else if (c == 0xF0) n = 4, lo = 0x90;
  else if (c >= 0xF1 && c <= 0xF3) n = 4;
  else if (c == 0xF4) n = 4, hi = 0x8F;
  else return 0;
  if (i + n > s.size()) return 0;
  if (b(i + 1) < lo || b(i + 1) > hi) return 0;
  for (size_t k = 2; k < n; ++k)
    if (b(i + k) < 0x80 || b(i + k) > 0xBF) return 0;
  return n;
}

std::string field(const char* p, const char* name, size_t limit, bool multiline) {
  const std::string s = p ? std::string(p) : std::string();
  if (s.size() > limit)
    throw CommandSampleError(std::string("command field '") + name + "' is " + std::to_string(s.size()) + " bytes; the limit is " +
                             std::to_string(limit));
  for (size_t i = 0; i < s.size();) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7F) {
      if (!(multiline && (c == '\t' || c == '\n' || c == '\r')))
        throw CommandSampleError(std::string("command field '") + name + "' has a control character (byte " + std::to_string(c) +
                                 " at offset " + std::to_string(i) + ")");
    }
    const size_t n = utf8_length(s, i);
    if (n == 0)
      throw CommandSampleError(std::string("command field '") + name + "' is not valid UTF-8 (at byte offset " + std::to_string(i) + ")");
    i += n;
  }
  return s;
}

}  // namespace

DecodedCommand decode_command(const fiberfem_Command& sample) {
  DecodedCommand d;
  d.run_id = field(sample.run_id, "run_id", kMaxCommandIdBytes, false);
  d.command_id = field(sample.command_id, "command_id", kMaxCommandIdBytes, false);
  d.client_id = field(sample.client_id, "client_id", kMaxCommandIdBytes, false);
  d.kind = field(sample.kind, "kind", kMaxCommandKindBytes, false);
  d.args = field(sample.args, "args", kMaxCommandArgsBytes, true);
  if (d.command_id.empty()) throw CommandSampleError("command field 'command_id' is empty");
  if (d.kind.empty()) throw CommandSampleError("command field 'kind' is empty");
  for (char c : d.kind)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_')
      throw CommandSampleError("command field 'kind' = '" + d.kind + "' is not a command name (letters, digits and _)");
  return d;
}

}  // namespace fiberfem::dds
