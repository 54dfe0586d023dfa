#!/usr/bin/env bash
# Out-of-tree plugin build test (see CMakeLists.txt). Arguments:
#   BUILD_DIR EXAMPLE_SRC WORK_DIR CMAKE GENERATOR CXX CC EIGEN_INCLUDE_DIRS
set -euo pipefail

build_dir=$1 example_src=$2 work=$3 cmake=$4 generator=$5 cxx=$6 cc=$7 eigen_dirs=$8
prefix="$work/prefix"
plugins="$work/plugins"

fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "== $*"; }
# Runs a command, keeping its output in $work/last.log; on failure prints it.
run() {
  if ! "$@" >"$work/last.log" 2>&1; then
    cat "$work/last.log" >&2
    fail "command failed: $*"
  fi
}
expect_in() {  # expect_in FILE TEXT...
  local file=$1; shift
  for text in "$@"; do
    grep -qF -- "$text" "$file" || { cat "$file" >&2; fail "'$text' not in output of the last command"; }
  done
}

rm -rf "$work"
mkdir -p "$work"

step "install $build_dir into $prefix"
run "$cmake" --install "$build_dir" --prefix "$prefix"
for f in bin/locforge lib/liblocforge_core.so include/locforge/abi.h include/locforge/plugin.h \
         include/locforge/version.h lib/cmake/locforge/locforgeConfig.cmake \
         lib/cmake/locforge/locforgeConfigVersion.cmake lib/cmake/locforge/locforgeTargets.cmake \
         lib/cmake/locforge/LocforgePlugin.cmake; do
  [[ -e "$prefix/$f" ]] || fail "$prefix/$f was not installed"
done
# Nothing installed may point back into the build tree.
if grep -rlF -- "$build_dir" "$prefix/lib/cmake" >/dev/null; then
  grep -rnF -- "$build_dir" "$prefix/lib/cmake" >&2
  fail "installed CMake files refer to the build tree"
fi

step "installed headers compile standalone and stay light"
eigen_flags=()
IFS=';' read -r -a eigen_list <<<"$eigen_dirs"
for d in "${eigen_list[@]}"; do [[ -n "$d" ]] && eigen_flags+=("-I$d"); done
heavy='#include *[<"](yaml-cpp|sqlite3|pcl|opencv2|ceres|gtest|cairo|ft2build|fontconfig)'
if grep -rnE "$heavy" "$prefix/include/locforge" >&2; then
  fail "an installed header includes a heavy dependency (see above)"
fi
count=0
while IFS= read -r header; do
  rel=${header#"$prefix/include/"}
  printf '#include "%s"\n#include "%s"\nint main() { return 0; }\n' "$rel" "$rel" >"$work/header_check.cc"
  run "$cxx" -std=c++17 -Wall -Wextra -Werror -fsyntax-only -I"$prefix/include" "${eigen_flags[@]}" \
      "$work/header_check.cc"
  count=$((count + 1))
done < <(find "$prefix/include/locforge" -name '*.h' | sort)
echo "   $count headers checked"
printf '#include "locforge/abi.h"\nint main(void) { return LF_ABI_VERSION == 0; }\n' >"$work/abi_check.c"
run "$cc" -std=c99 -Wall -Wextra -Werror -pedantic -fsyntax-only -I"$prefix/include" "$work/abi_check.c"

step "configure and build the example plugin against the install"
run "$cmake" -S "$example_src" -B "$work/build" -G "$generator" -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_PREFIX_PATH="$prefix" -DLOCFORGE_PLUGIN_OUTPUT_DIR="$plugins"
expect_in "$work/last.log" "Build files have been written"
run "$cmake" --build "$work/build"
library="$plugins/libhello_plugin.so"
[[ -f "$library" ]] || fail "$library was not built"
# One exported entry point; the stage classes stay hidden.
nm -D --defined-only "$library" >"$work/symbols.txt"
expect_in "$work/symbols.txt" "locforge_plugin_entry"
if grep -q "thirdparty" "$work/symbols.txt"; then fail "plugin exports its internals"; fi

host="$prefix/bin/locforge"
export LOCFORGE_PLUGIN_PATH="$plugins"

step "locforge plugins list"
run "$host" plugins list
expect_in "$work/last.log" "thirdparty/text_files" "thirdparty/word_count"
# The installed host finds the installed plugins, never the build tree's.
if grep -qF -- "$build_dir/lib/locforge/plugins" "$work/last.log"; then
  cat "$work/last.log" >&2
  fail "the installed host loaded plugins from the build tree"
fi
installed_plugins=("$prefix"/lib/locforge/plugins/*.so)
if [[ -e "${installed_plugins[0]}" ]]; then
  expect_in "$work/last.log" "$prefix/lib/locforge/plugins/"
fi

step "locforge plugins describe thirdparty/word_count"
run "$host" plugins describe thirdparty/word_count
expect_in "$work/last.log" "thirdparty/word_count" "hello_plugin 0.4.0" "min_length" \
  "range: [1, 100]" "case_sensitive" "Counts the words" "texts: thirdparty.texts" \
  "report: report"

step "locforge run a graph using the plugin"
cat >"$work/graph.yaml" <<'YAML'
locforge: 1
description: Word counts of generated text files (out-of-tree plugin test)
nodes:
  texts:
    stage: thirdparty/text_files
    params: {text: "The cat saw the other cat", copies: 3}
  count:
    stage: thirdparty/word_count
    inputs: {texts: texts.texts}
    params: {min_length: 3}
YAML
run "$host" run "$work/graph.yaml" --workspace "$work/ws"
expected=$'cat\t6\nthe\t6\nother\t3\nsaw\t3\ntotal\t18'
report="$work/ws/nodes/count/counts.tsv"
[[ -f "$report" ]] || fail "$report was not written"
[[ "$(cat "$report")" == "$expected" ]] || { cat "$report" >&2; fail "unexpected counts.tsv"; }
[[ -f "$work/ws/nodes/texts/doc_002.txt" ]] || fail "text_files did not write doc_002.txt"
# The plot library of the installed SDK draws (its Cairo is a private dependency).
figure="$work/ws/nodes/count/counts"
[[ "$(head -c 8 "$figure.png" | od -An -tx1 | tr -d ' \n')" == "89504e470d0a1a0a" ]] \
  || fail "$figure.png is not a PNG"
(( $(stat -c %s "$figure.png") > 2000 )) || fail "$figure.png is nearly empty"
grep -q "<title>Words by rank</title>" "$figure.svg" || fail "$figure.svg lacks its title"
# The exported targets' interface does not name Cairo (a private dependency).
if grep -li "cairo" "$prefix"/lib/cmake/locforge/locforgeTargets*.cmake >/dev/null; then
  fail "the installed targets name Cairo"
fi

step "a second run is cached, a changed parameter recomputes"
run "$host" run "$work/graph.yaml" --workspace "$work/ws"
[[ "$(cat "$report")" == "$expected" ]] || fail "counts.tsv changed on a cached run"
run "$host" run "$work/graph.yaml" --workspace "$work/ws" --set count.min_length=4
[[ "$(cat "$report")" == $'other\t3\ntotal\t3' ]] || { cat "$report" >&2; fail "min_length=4 not applied"; }

step "bad parameters are refused through the plugin's declarations"
if "$host" run "$work/graph.yaml" --workspace "$work/ws" --set count.min_length=0 \
    >"$work/last.log" 2>&1; then
  fail "min_length=0 was accepted"
fi
expect_in "$work/last.log" "min_length"

echo "PASS: out-of-tree plugin built against $prefix and run by the installed host"
