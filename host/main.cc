// The `locforge` executable: everything is in cli.cc; this only guards it.
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "cli.h"

int main(int argc, char** argv) {
  try {
    return locforge::host::Main(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const std::exception& e) {
    std::cerr << "locforge: error: " << e.what() << "\n";
  } catch (...) {
    std::cerr << "locforge: error: unknown exception\n";
  }
  return 1;
}
