// Shared pieces of the command-line layer: help texts, usage errors, option
// parsing, plugin loading with warnings. Only this layer prints.
#ifndef LOCFORGE_HOST_CLI_H_
#define LOCFORGE_HOST_CLI_H_

#include <filesystem>
#include <string>
#include <vector>

#include "commands.h"
#include "locforge/runtime/registry.h"

namespace locforge::host {

namespace fs = std::filesystem;

// The whole program: dispatches to a subcommand; returns the exit code.
int Main(const Args& args);

std::string VersionText();
// Help of `command` ("" for the top-level help), or "" when unknown.
std::string HelpText(const std::string& command);
bool WantsHelp(const Args& args);
// Prints "locforge COMMAND: message" and a pointer to --help; returns 2.
int UsageError(const std::string& command, const std::string& message);

// Reads the value of an option at args[*i] ("--name value" or "--name=value").
// Returns false when `args[*i]` is not that option; throws std::invalid_argument
// when the value is missing.
bool TakeOption(const Args& args, size_t* i, const std::string& name, std::string* value);

// Loads the default plugin folders plus `extra` ones (each folder once).
// Returns the libraries refused from `extra` folders (errors for the graph
// that names them); libraries refused elsewhere are printed as one warning
// line each on stderr.
std::vector<runtime::PluginProblem> LoadPlugins(runtime::Registry* registry,
                                                const std::vector<fs::path>& extra);

}  // namespace locforge::host

#endif  // LOCFORGE_HOST_CLI_H_
