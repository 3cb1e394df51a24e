// XML text and attribute escaping for the files we write ourselves (SVG plots, GeoTIFF metadata),
// and its inverse for the GeoTIFF metadata we read back.
#pragma once

#include <cstddef>
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

/// `s` with the five predefined entities (&amp; &lt; &gt; &quot; &apos;) and numeric character
/// references below 128 replaced; anything else after '&' is kept as it is.
inline std::string xml_unescape(const std::string& s) {
  std::string o;
  o.reserve(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '&') {
      o += s[i];
      continue;
    }
    const std::size_t end = s.find(';', i);
    const std::string ent = end == std::string::npos ? std::string() : s.substr(i + 1, end - i - 1);
    char c = 0;
    if (ent == "amp") c = '&';
    else if (ent == "lt") c = '<';
    else if (ent == "gt") c = '>';
    else if (ent == "quot") c = '"';
    else if (ent == "apos") c = '\'';
    else if (ent.size() >= 2 && ent.size() <= 4 && ent[0] == '#' && ent.find_first_not_of("0123456789", 1) == std::string::npos) {
      const int v = std::stoi(ent.substr(1));
      if (v > 0 && v < 128) c = static_cast<char>(v);
    }
    if (c == 0) {
      o += '&';
      continue;
    }
    o += c;
    i = end;
  }
  return o;
}

}  // namespace pcdp::io::detail
