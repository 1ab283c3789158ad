#include "bridges/qtm/parameters_xml.hpp"

#include <charconv>
#include <cstdint>
#include <set>

#include "common/safe_text.hpp"
#include "common/utf8.hpp"

namespace fabrik::qtm {

namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }
bool is_name_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '-' || c == '.' || c == ':' || static_cast<unsigned char>(c) >= 0x80;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

// Walks the document, keeping the path of open elements and the text of the
// innermost one; the 3D extraction happens on each end tag.
class Reader {
 public:
  Reader(std::string_view xml, const XmlLimits& limits, Parameters3d& out, std::string& error)
      : s_(xml), limits_(limits), out_(out), error_(error) {}

  bool run() {
    if (s_.size() > limits_.max_bytes) return fail("the XML is larger than the limit");
    skip_space();
    if (starts("<?xml")) {
      const std::size_t end = s_.find("?>", i_);
      if (end == std::string_view::npos) return fail("unterminated XML declaration");
      i_ = end + 2;
    }
    bool root_seen = false;
    while (i_ < s_.size()) {
      if (s_[i_] != '<') {
        if (path_.empty()) {
          if (!is_space(s_[i_])) return fail("text outside the root element");
          ++i_;
          continue;
        }
        if (!read_text()) return false;
        continue;
      }
      if (starts("<!--")) {
        const std::size_t end = s_.find("-->", i_ + 4);
        if (end == std::string_view::npos) return fail("unterminated comment");
        i_ = end + 3;
      } else if (starts("<!") || starts("<?")) {
        return fail("DOCTYPE, CDATA and processing instructions are not accepted");
      } else if (starts("</")) {
        if (!read_end_tag()) return false;
      } else {
        if (path_.empty() && root_seen) return fail("more than one root element");
        root_seen = true;
        if (!read_start_tag()) return false;
      }
    }
    if (!path_.empty()) return fail("unclosed element <" + safe_text(path_.back(), 64) + ">");
    if (!root_seen) return fail("no XML element");
    if (!seen_3d_) return fail("no The_3D block in the parameters");
    if (declared_labels_ >= 0 && static_cast<std::size_t>(declared_labels_) != out_.labels.size())
      return fail("Labels says " + std::to_string(declared_labels_) + " but there are " +
                  std::to_string(out_.labels.size()) + " Label blocks");
    return true;
  }

 private:
  bool fail(std::string why) {
    error_ = "3D parameters XML: " + std::move(why);
    return false;
  }
  bool starts(std::string_view p) const { return s_.substr(i_, p.size()) == p; }
  void skip_space() {
    while (i_ < s_.size() && is_space(s_[i_])) ++i_;
  }

  bool read_name(std::string& name) {
    const std::size_t b = i_;
    while (i_ < s_.size() && is_name_char(s_[i_])) ++i_;
    if (i_ == b) return fail("an element or attribute without a name");
    name.assign(s_.substr(b, i_ - b));
    return true;
  }

  bool read_start_tag() {
    ++i_;  // '<'
    std::string name;
    if (!read_name(name)) return false;
    for (;;) {  // attributes: checked for form, their values unused
      skip_space();
      if (i_ >= s_.size()) return fail("unterminated tag <" + safe_text(name, 64) + ">");
      if (s_[i_] == '>' || starts("/>")) break;
      std::string attribute;
      if (!read_name(attribute)) return false;
      skip_space();
      if (i_ >= s_.size() || s_[i_] != '=') return fail("attribute " + safe_text(attribute, 64) + " without a value");
      ++i_;
      skip_space();
      if (i_ >= s_.size() || (s_[i_] != '"' && s_[i_] != '\'')) return fail("unquoted attribute value");
      const std::size_t end = s_.find(s_[i_], i_ + 1);
      if (end == std::string_view::npos) return fail("unterminated attribute value");
      i_ = end + 1;
    }
    if (path_.empty() && name.rfind("QTM_Parameters", 0) != 0)
      return fail("the root element is <" + safe_text(name, 64) + ">, not <QTM_Parameters_Ver_n.n>");
    const bool empty_element = s_[i_] == '/';
    i_ += empty_element ? 2 : 1;
    if (path_.size() >= limits_.max_depth) return fail("elements nested deeper than the limit");
    path_.push_back(std::move(name));
    text_.clear();
    if (empty_element) return close_element();
    return true;
  }

  bool read_end_tag() {
    i_ += 2;
    std::string name;
    if (!read_name(name)) return false;
    skip_space();
    if (i_ >= s_.size() || s_[i_] != '>') return fail("unterminated end tag </" + safe_text(name, 64) + ">");
    ++i_;
    if (path_.empty() || path_.back() != name) return fail("end tag </" + safe_text(name, 64) + "> does not match");
    return close_element();
  }

  bool read_text() {
    while (i_ < s_.size() && s_[i_] != '<') {
      if (text_.size() > limits_.max_text_bytes) return fail("a text longer than the limit");
      if (s_[i_] != '&') {
        text_ += s_[i_++];
        continue;
      }
      const std::size_t end = s_.find(';', i_);
      if (end == std::string_view::npos || end - i_ > 10) return fail("unterminated entity");
      const std::string_view ent = s_.substr(i_ + 1, end - i_ - 1);
      i_ = end + 1;
      if (ent == "amp") text_ += '&';
      else if (ent == "lt") text_ += '<';
      else if (ent == "gt") text_ += '>';
      else if (ent == "quot") text_ += '"';
      else if (ent == "apos") text_ += '\'';
      else if (ent.size() > 1 && ent[0] == '#') {
        const bool hex = ent[1] == 'x';
        const std::string_view digits = ent.substr(hex ? 2 : 1);
        std::uint32_t cp = 0;
        const auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), cp, hex ? 16 : 10);
        if (digits.empty() || ec != std::errc() || p != digits.data() + digits.size() || cp == 0 ||
            cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
          return fail("bad character reference");
        append_utf8(text_, cp);
      } else {
        return fail("unknown entity &" + safe_text(ent, 16) + ";");
      }
    }
    return true;
  }

  // The path of the element being closed, from the root: root/The_3D/...
  bool in_3d(std::size_t depth) const { return path_.size() == depth && path_[1] == "The_3D"; }

  bool close_element() {
    const std::string_view text = trim(text_);
    if (path_.size() == 2 && path_[1] == "The_3D") {
      if (seen_3d_) return fail("more than one The_3D block");
      seen_3d_ = true;
    } else if (in_3d(3) && path_[2] == "AxisUpwards") {
      out_.axis_upwards.assign(text);
    } else if (in_3d(3) && path_[2] == "Labels") {
      int n = -1;
      const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), n);
      if (ec != std::errc() || p != text.data() + text.size() || n < 0)
        return fail("Labels is not a count: '" + safe_text(text, 32) + "'");
      declared_labels_ = n;
    } else if (in_3d(4) && path_[2] == "Label" && path_[3] == "Name") {
      if (label_name_seen_) return fail("a Label with two Names");
      if (text.empty()) return fail("a Label with an empty Name");
      label_name_.assign(text);
      label_name_seen_ = true;
    } else if (in_3d(3) && path_[2] == "Label") {
      if (!label_name_seen_) return fail("a Label without a Name");
      if (out_.labels.size() >= limits_.max_labels) return fail("more labels than the limit");
      if (!names_.insert(label_name_).second) return fail("the label '" + safe_text(label_name_, 64) + "' appears twice");
      out_.labels.push_back(label_name_);
      label_name_seen_ = false;
    }
    path_.pop_back();
    text_.clear();
    return true;
  }

  std::string_view s_;
  const XmlLimits& limits_;
  Parameters3d& out_;
  std::string& error_;
  std::size_t i_ = 0;
  std::vector<std::string> path_;
  std::string text_;
  bool seen_3d_ = false;
  long declared_labels_ = -1;
  std::string label_name_;
  bool label_name_seen_ = false;
  std::set<std::string> names_;
};

void append_escaped(std::string& out, std::string_view s) {
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
}

}  // namespace

bool read_parameters_3d(std::string_view xml, Parameters3d& out, std::string& error,
                        const XmlLimits& limits) {
  out = {};
  error.clear();
  Reader reader(xml, limits, out, error);
  return reader.run();
}

std::string write_parameters_3d(const Parameters3d& params, std::string_view protocol_version) {
  const std::string root = "QTM_Parameters_Ver_" + std::string(protocol_version);
  std::string x = "<" + root + ">\n  <The_3D>\n";
  if (!params.axis_upwards.empty()) {
    x += "    <AxisUpwards>";
    append_escaped(x, params.axis_upwards);
    x += "</AxisUpwards>\n";
  }
  x += "    <Labels>" + std::to_string(params.labels.size()) + "</Labels>\n";
  for (const std::string& name : params.labels) {
    x += "    <Label>\n      <Name>";
    append_escaped(x, name);
    x += "</Name>\n      <RGBColor>0</RGBColor>\n    </Label>\n";
  }
  x += "  </The_3D>\n</" + root + ">\n";
  return x;
}

}  // namespace fabrik::qtm
