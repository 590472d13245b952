#pragma once
/// @file SHA-256 of a byte string (OpenSSL), for scene and run identities.

#include <string>

namespace fiberfem::io {

/// Lower-case hex SHA-256 of `bytes` (64 characters).
std::string sha256_hex(const std::string& bytes);

}  // namespace fiberfem::io
