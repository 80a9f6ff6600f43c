#!/usr/bin/env python3
"""Fails when a function or lambda body in the sources is longer than the house rule allows:
100 lines in tools/verbs/ (a verb parses, calls the library, writes), 150 elsewhere; tests and
benchmarks excepted (case tables). A body opens with '{' ending a line that looks like a function
signature (or a BODYMODEL_VERB) and runs to the matching '}'; comments and strings are ignored.
Usage: scripts/check_function_lengths.py [REPO]"""
import os
import re
import sys

SIG = re.compile(r'(\)\s*(const)?\s*(noexcept)?\s*(override)?\s*(->\s*[\w:<>,\s*&]+)?\s*\{\s*$)|'
                 r'(BODYMODEL_VERB\(\w+\)\s*\{\s*$)')
CONTROL = re.compile(r'^\s*(\}\s*)?(if|for|while|switch|catch|else|do)\b')
FOLDERS = ["core", "registration", "encoding", "regression", "model", "skinning", "population", "python", "tools"]


def code_of(line):
    line = re.sub(r'"(\\.|[^"\\])*"', '""', line)
    line = re.sub(r"'(\\.|[^'\\])*'", "''", line)
    return line.split('//')[0]


def bodies(path):
    """(lines, first line, text) of every function body, counted from the first line of its
    signature (the line after the previous statement, block or blank line)."""
    stack, out = [], []
    statement_start = 0
    for i, raw in enumerate(open(path, errors="replace").read().split("\n")):
        line = code_of(raw)
        stripped = line.rstrip()
        if not stripped.strip():
            statement_start = i + 1
            continue
        opener = stripped.endswith("{") and SIG.search(stripped) and not CONTROL.search(stripped)
        for j, ch in enumerate(line):
            if ch == "{":
                start = statement_start if opener and j == len(stripped) - 1 else i
                stack.append((start, bool(opener) and j == len(stripped) - 1, raw.strip()[:70]))
            elif ch == "}" and stack:
                start, is_function, name = stack.pop()
                if is_function:
                    out.append((i - start + 1, start + 1, name))
        if stripped.endswith((";", "{", "}")) or stripped.lstrip().startswith("#"):
            statement_start = i + 1
    return out


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else "."
    problems = 0
    for folder in FOLDERS:
        for d, _, files in os.walk(os.path.join(repo, folder)):
            for f in sorted(files):
                if not f.endswith((".cc", ".h")):
                    continue
                path = os.path.join(d, f)
                rel = os.path.relpath(path, repo)
                limit = 100 if rel.startswith(os.path.join("tools", "verbs")) else 150
                for n, line, name in bodies(path):
                    if n > limit:
                        print(f"{rel}:{line}: {n} lines (limit {limit}): {name}")
                        problems += 1
    print(f"check_function_lengths: {problems} function(s) over the limit")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
