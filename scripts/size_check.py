#!/usr/bin/env python3
"""Keeps the code a reader can hold: no Rust source file over 1 000 lines and no function
outside the test trees over 110 lines, the size the code holds once its functions are split by
responsibility (a named step with its own doc comment), so that a longer function is a sign of
two jobs in one. A function spans from its `fn` line to the closing brace at the same
indentation (rustfmt's layout, which CI enforces). Prints every offender and exits 1 if any.

    python3 scripts/size_check.py            # the whole workspace
"""
import pathlib
import re
import sys

MAX_FILE = 1000
MAX_FN = 110
FN = re.compile(r"^(\s*)(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+\"C\"\s+)?fn\s+(\w+)")


def functions(lines):
    """(name, first line, length) of every function with a body."""
    for i, line in enumerate(lines):
        m = FN.match(line)
        if not m:
            continue
        close = m.group(1) + "}"
        j = i
        while j < len(lines) and "{" not in lines[j] and not lines[j].rstrip().endswith(";"):
            j += 1
        if j == len(lines) or "{" not in lines[j]:
            continue  # a declaration without a body (trait item, extern block)
        if lines[j].rstrip().endswith("}"):
            yield m.group(8), i + 1, j - i + 1  # a body on one line
            continue
        for k in range(j + 1, len(lines)):
            if lines[k].rstrip() == close:
                yield m.group(8), i + 1, k - i + 1
                break


def main():
    root = pathlib.Path(__file__).resolve().parent.parent
    bad = []
    for path in sorted(root.glob("crates/**/*.rs")):
        if "target" in path.parts:
            continue
        lines = path.read_text(encoding="utf-8").split("\n")
        rel = path.relative_to(root)
        if len(lines) > MAX_FILE:
            bad.append(f"{rel}: {len(lines)} lines (at most {MAX_FILE})")
        if "tests" in rel.parts:
            continue  # a test reads as one story; its length is its scenario's
        for name, first, length in functions(lines):
            if length > MAX_FN:
                bad.append(f"{rel}:{first}: fn {name} has {length} lines (at most {MAX_FN})")
    for b in bad:
        print(b)
    if bad:
        sys.exit(1)
    print(f"size check: every Rust file ≤ {MAX_FILE} lines, every function ≤ {MAX_FN} lines")


if __name__ == "__main__":
    main()
