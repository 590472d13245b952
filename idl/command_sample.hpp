#pragma once
/// @file The command decoder: one received fiberfem::Command sample (idl/control.idl)
/// checked field by field before anything acts on it (docs/commands.md, "Limits";
/// docs/bad-input.md). What passes is well-formed text of bounded size; whether the kind
/// and its arguments make sense is the run's to judge (RunControl::apply, the replay).

#include "control.h"

#include <stdexcept>
#include <string>

namespace fiberfem::dds {

/// Limits on the fields of a command sample, bytes.
inline constexpr size_t kMaxCommandIdBytes = 256;    ///< run_id, command_id, client_id.
inline constexpr size_t kMaxCommandKindBytes = 64;   ///< kind.
inline constexpr size_t kMaxCommandArgsBytes = 1 << 20;  ///< args (1 MiB).

/// A command sample refused before it reached the run: the message names the field.
class CommandSampleError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// The fields of a command sample as text.
struct DecodedCommand {
  std::string run_id, command_id, client_id, kind, args;
};

/// Decodes and checks `sample`: every field present (a null pointer is an empty field),
/// within its limit, valid UTF-8 without control characters (tabs and line breaks allowed
/// in args); command_id and kind not empty; kind a word of letters, digits and '_'.
/// @throws CommandSampleError naming the field and what is wrong.
DecodedCommand decode_command(const fiberfem_Command& sample);

}  // namespace fiberfem::dds
