// Numbers into message text: one printf-style formatter for every library's error, warning and
// repair messages (type-checked by the compiler, never truncated).
#pragma once

#include <cstdarg>
#include <cstdio>
#include <string>

namespace rheo {

/// printf's `fmt` with `...` as a string, e.g. Format("%.1f px", gap), Format("[%g, %g]", a, b).
[[gnu::format(printf, 1, 2)]] inline std::string Format(const char* fmt, ...) {
  char buf[256];
  va_list args;
  va_start(args, fmt);
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  std::string out;
  if (n < 0) {
    va_end(again);
    return out;
  }
  if (static_cast<size_t>(n) < sizeof buf) {
    out.assign(buf, static_cast<size_t>(n));
  } else {
    out.resize(static_cast<size_t>(n));
    std::vsnprintf(out.data(), out.size() + 1, fmt, again);
  }
  va_end(again);
  return out;
}

/// A number as %g writes it (6 significant digits, exponent when large or small): 0.25, 1e-06.
inline std::string Num(double v) {
  return Format("%g", v);
}

/// A number with `digits` digits after the point: Fixed(2.345, 1) = "2.3".
inline std::string Fixed(double v, int digits) {
  return Format("%.*f", digits, v);
}

}  // namespace rheo
