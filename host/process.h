// Runs a program with an argument vector (posix_spawnp: no shell, nothing
// is re-parsed), capturing its standard output and error.
#ifndef LOCFORGE_HOST_PROCESS_H_
#define LOCFORGE_HOST_PROCESS_H_

#include <string>
#include <vector>

namespace locforge::host {

struct ProcessResult {
  bool started = false;  // false: the program could not be run (see error)
  int exit_code = -1;    // -1 when killed by a signal
  bool timed_out = false;
  std::string out, err;
  std::string error;     // why it did not start or finish
  bool ok() const { return started && !timed_out && exit_code == 0; }
};

// Runs argv[0] (searched on PATH) with argv, stdin from /dev/null. Kills it
// after `timeout_seconds` (SIGTERM, then SIGKILL 2 s later).
ProcessResult RunProcess(const std::vector<std::string>& argv, double timeout_seconds = 120);

// "prog 'arg one' two": for messages and logs only, never for a shell.
std::string DisplayCommand(const std::vector<std::string>& argv);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_PROCESS_H_
