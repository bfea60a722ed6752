#include "server/cmd/flags.h"

#include <cstdlib>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"

namespace actopo {

void FlagParser::Add(const std::string& name, std::string* value, const std::string& help) {
  flags_.push_back({name, help, *value, false, [value](const std::string& v) {
                      *value = v;
                      return true;
                    }});
}

void FlagParser::Add(const std::string& name, int* value, const std::string& help) {
  flags_.push_back({name, help, std::to_string(*value), false,
                    [value](const std::string& v) { return absl::SimpleAtoi(v, value); }});
}

void FlagParser::Add(const std::string& name, double* value, const std::string& help) {
  flags_.push_back({name, help, absl::StrCat(*value), false,
                    [value](const std::string& v) { return absl::SimpleAtod(v, value); }});
}

void FlagParser::Add(const std::string& name, bool* value, const std::string& help) {
  flags_.push_back({name, help, *value ? "true" : "false", true,
                    [value](const std::string& v) { return absl::SimpleAtob(v, value); }});
}

FlagParser::Flag* FlagParser::Find(const std::string& name) {
  for (Flag& f : flags_) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

absl::Status FlagParser::Parse(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "--help" || arg == "-h") {
      help_requested_ = true;
      return absl::OkStatus();
    }
    if (arg.rfind("--", 0) != 0) {
      return absl::InvalidArgumentError(absl::StrCat("unexpected argument '", arg, "'"));
    }
    std::string name = arg.substr(2), value;
    bool has_value = false;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      has_value = true;
    }
    Flag* flag = Find(name);
    if (flag == nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat("unknown flag --", name, " (see ", program_, " --help)"));
    }
    if (!has_value) {
      if (flag->is_bool) {
        value = "true";
      } else if (i + 1 < argc) {
        value = argv[++i];
      } else {
        return absl::InvalidArgumentError(absl::StrCat("flag --", name, " needs a value"));
      }
    }
    if (!flag->set(value)) {
      return absl::InvalidArgumentError(
          absl::StrCat("flag --", name, ": cannot parse '", value, "'"));
    }
  }
  return absl::OkStatus();
}

std::string FlagParser::Usage() const {
  std::string out = absl::StrCat(program_, ": ", summary_, "\n\nFlags:\n");
  for (const Flag& f : flags_) {
    absl::StrAppend(
        &out, "  --", f.name, f.is_bool ? "" : " VALUE", "\n      ", f.help,
        f.default_value.empty() ? "" : absl::StrCat(" (default: ", f.default_value, ")"), "\n");
  }
  return out;
}

}  // namespace actopo
