// A shared library that is not a locforge plugin: no entry symbol.
extern "C" __attribute__((visibility("default"))) int lftest_not_a_plugin(int x) { return x + 1; }
