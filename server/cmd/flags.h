// A small command-line parser for the main programs: `--name value`, `--name=value` and boolean
// `--name`. Kebab-case names as documented (--buffer-ratio), which absl flags cannot spell.
//
//   FlagParser flags("actopo-bench", "Runs one algorithm in-process.");
//   flags.Add("block-size", &options.block_size, "max vertices per octree leaf");
//   RETURN_IF_ERROR(flags.Parse(argc, argv));
#ifndef ACTOPO_SERVER_CMD_FLAGS_H_
#define ACTOPO_SERVER_CMD_FLAGS_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace actopo {

class FlagParser {
 public:
  FlagParser(std::string program, std::string summary)
      : program_(std::move(program)), summary_(std::move(summary)) {}

  void Add(const std::string& name, std::string* value, const std::string& help);
  void Add(const std::string& name, int* value, const std::string& help);
  void Add(const std::string& name, double* value, const std::string& help);
  void Add(const std::string& name, bool* value, const std::string& help);

  // Errors name the flag and the value. `--help` sets help_requested() and returns OK.
  absl::Status Parse(int argc, char** argv);
  bool help_requested() const { return help_requested_; }
  std::string Usage() const;

 private:
  struct Flag {
    std::string name;
    std::string help;
    std::string default_value;
    bool is_bool = false;
    std::function<bool(const std::string&)> set;
  };
  Flag* Find(const std::string& name);

  std::string program_, summary_;
  std::vector<Flag> flags_;
  bool help_requested_ = false;
};

}  // namespace actopo

#endif  // ACTOPO_SERVER_CMD_FLAGS_H_
