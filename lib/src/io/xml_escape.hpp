// XML text and attribute escaping for the files we write ourselves (SVG plots, GeoTIFF metadata).
#pragma once

#include <string>

namespace pcdp::io::detail {

/// `s` with &, <, > and " escaped: safe in XML text and in a double-quoted attribute.
inline std::string xml_escape(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': o += "&amp;"; break;
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

}  // namespace pcdp::io::detail
