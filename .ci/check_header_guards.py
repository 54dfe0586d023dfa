#!/usr/bin/env python3
"""Every header's include guard names its file.

sdk/include/locforge/a/b.h -> LOCFORGE_A_B_H_ (its include path);
any other x/y.h -> LOCFORGE_X_Y_H_ (its path in the repository).
--fix rewrites the guards in place. Exit 1 naming each header that differs.
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
SDK_INCLUDE = "sdk/include/locforge/"


def expected_guard(rel: str) -> str:
    name = rel[len(SDK_INCLUDE):] if rel.startswith(SDK_INCLUDE) else rel
    return "LOCFORGE_" + re.sub(r"[^A-Za-z0-9]", "_", name).upper() + "_"


def main() -> int:
    fix = "--fix" in sys.argv[1:]
    bad = 0
    for folder in ("sdk", "host", "plugins"):
        for path in sorted((ROOT / folder).rglob("*.h")):
            rel = path.relative_to(ROOT).as_posix()
            text = path.read_text()
            m = re.search(r"^#ifndef (\w+)\n#define \1\n", text, re.M)
            if not m:
                print(f"{rel}: no '#ifndef X / #define X' include guard")
                bad += 1
                continue
            want = expected_guard(rel)
            if m.group(1) == want:
                continue
            if fix:
                text = re.sub(rf"\b{m.group(1)}\b", want, text)
                path.write_text(text)
            else:
                print(f"{rel}: guard {m.group(1)}, expected {want}")
                bad += 1
    if bad:
        print(f"{bad} headers whose guard does not name the file")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
