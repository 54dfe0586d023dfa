// Subcommands of the `locforge` executable. Each takes the arguments after its
// own name, prints its --help, returns the process exit code (0 ok, 1 the
// work failed, 2 bad usage or bad input) and never throws.
#ifndef LOCFORGE_HOST_COMMANDS_H_
#define LOCFORGE_HOST_COMMANDS_H_

#include <string>
#include <vector>

namespace locforge::host {

using Args = std::vector<std::string>;

int PluginsCommand(const Args& args);   // plugins list | describe KIND/NAME
int ValidateCommand(const Args& args);  // validate GRAPH.yaml [--set k=v ...]
int RunCommand(const Args& args);       // run GRAPH.yaml --workspace DIR ...
int KaptureCommand(const Args& args);   // kapture info DIR | copy SRC DST   (cmd_kapture.cc)
int ColmapCommand(const Args& args);    // colmap import|export ...         (cmd_colmap.cc)
int CollectCommand(const Args& args);   // collect WORKSPACE NODE/FILE       (cmd_collect.cc)
int StatusCommand(const Args& args);    // status WORKSPACE [--wait]         (cmd_status.cc)
int ReportCommand(const Args& args);    // report WORKSPACE [-o FILE]        (cmd_report.cc)

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_COMMANDS_H_
