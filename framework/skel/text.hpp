#pragma once
// Text and number helpers shared by the YAML pipeline reader, the file formats and the CLI: one
// definition of "trim", "split", "a number" and "lower case" (C locale, ASCII; never the user's
// locale, so files read and write the same everywhere).
#include <charconv>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace skel::text {

// `s` without leading and trailing white space.
std::string trim(std::string_view s);

// `s` in ASCII lower case (file extensions, header names).
std::string to_lower(std::string_view s);

// The fields between the separators: n separators give n + 1 fields, empty ones included.
std::vector<std::string> split(std::string_view s, char sep);

// The lines of `text` without their "\n" / "\r\n" ends; a final newline starts no extra line.
std::vector<std::string> split_lines(std::string_view text);

// The whole of `s` as a number (std::from_chars: no white space, no leading '+'; "inf" and "nan"
// are numbers). False, with `out` unspecified, when `s` is empty or anything is left over.
bool parse_int(std::string_view s, int64_t& out);
bool parse_double(std::string_view s, double& out);

// `v` with `significant_digits` digits, as printf's "%.<digits>g" in the C locale (9 round-trips a
// float, 17 a double).
// Inline: the graph writers call it per value.
inline void append_double(std::string& out, double v, int significant_digits) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general, significant_digits);
  out.append(buf, r.ptr);
}
std::string format_double(double v, int significant_digits);

// Base64 (RFC 4648, padded) of any bytes.
std::string base64_encode(std::string_view bytes);
// Bytes of base64 text. White space is skipped; '=' ends a stream, so several padded streams back to
// back decode to their concatenated bytes (VTK writes a compression header and its blocks so).
// Throws InputError "WHAT: 'c' at character N is not base64" or "... ends in the middle of a group
// (truncated)".
std::string base64_decode(std::string_view text, const std::string& what);

}  // namespace skel::text
