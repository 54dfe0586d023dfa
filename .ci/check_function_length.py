#!/usr/bin/env python3
"""Lists the C++ functions of sdk/, host/ and plugins/ longer than a limit, tests and benches aside.
Each function's first and last line come from Universal Ctags (`--fields=+ne`); its length counts
both, so a lambda or a local class is counted in the function that holds it (and on its own too).
Usage: python3 .ci/check_function_length.py [--limit N] [--allow NAME]... [--all] [PATH ...]
  --limit N     longest allowed function, in lines (default 80)
  --allow NAME  a function (qualified name as listed) allowed to be longer, for now (repeatable)
  --all         print every function with its length, longest first, and exit 0
  PATH          files or folders to check instead of sdk/ host/ plugins/ (relative to the repository)
Exit 0 when none is longer, 1 (one line per function: path:line: N lines: name) when some are,
2 when ctags is missing or is not Universal Ctags (77 then with --skip-code-77, for ctest)."""
import argparse
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_DIRS = ["sdk", "host", "plugins"]
# Tests, benches, fuzzers and their helpers: the rule is for the code that ships.
SKIP_FILE = re.compile(r"(_test|_bench|_fuzz)\.(cc|cpp|h)$|(^|/)(test|testing)_[^/]*\.h$")
SKIP_DIR = re.compile(r"(^|/)(testdata|testkit|bench|benches|tests?)(/|$)")


def sources(paths):
    for top in paths:
        top = (ROOT / top).resolve()
        files = [top] if top.is_file() else sorted(top.rglob("*"))
        for f in files:
            rel = f.relative_to(ROOT).as_posix()
            if f.suffix in (".cc", ".cpp", ".h", ".hpp") and not SKIP_FILE.search(rel) \
                    and not SKIP_DIR.search(str(Path(rel).parent)):
                yield rel


def functions(files):
    """(path, first line, last line, qualified name) of every function definition ctags finds."""
    cmd = ["ctags", "--output-format=json", "--languages=C++", "--language-force=C++",
           "--kinds-C++=f", "--fields=+neZ", "-f", "-", *files]
    out = subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stdout
    for line in out.splitlines():
        tag = json.loads(line)
        if tag.get("_type") != "tag" or "end" not in tag:
            continue
        scope = tag.get("scope", "")
        name = f"{scope}::{tag['name']}" if scope else tag["name"]
        name = re.sub(r"__anon[0-9a-f]+", "(anonymous)", name)
        yield tag["path"], int(tag["line"]), int(tag["end"]), name


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=80)
    ap.add_argument("--allow", action="append", default=[])
    ap.add_argument("--all", action="store_true")
    ap.add_argument("--skip-code-77", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("paths", nargs="*", default=DEFAULT_DIRS)
    args = ap.parse_args()
    ctags = shutil.which("ctags")
    if not ctags or "Universal Ctags" not in subprocess.run(
            [ctags, "--version"], capture_output=True, text=True).stdout:
        print("check_function_length.py needs Universal Ctags (apt-get install universal-ctags)",
              file=sys.stderr)
        return 77 if args.skip_code_77 else 2
    found = [(end - first + 1, path, first, name)
             for path, first, end, name in functions(list(sources(args.paths)))]
    found.sort(key=lambda f: (-f[0], f[1], f[2]))
    if args.all:
        for n, path, first, name in found:
            print(f"{path}:{first}: {n} lines: {name}")
        return 0
    over = [f for f in found if f[0] > args.limit and f[3] not in args.allow]
    for n, path, first, name in over:
        print(f"{path}:{first}: {n} lines: {name}")
    if over:
        print(f"{len(over)} functions over {args.limit} lines", file=sys.stderr)
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
