#!/usr/bin/env python3
"""Checks the documentation: README.md stays a short user's guide, every relative link in
README.md and docs/*.md resolves inside the repository (files and #anchors), and no source or
document points at design documents outside the repository.

Usage: scripts/check_docs.py [REPOSITORY_ROOT]     (default: the folder above this script)
Exit status 0 when every check passes, 1 otherwise (each problem printed on its own line).
Python 3 standard library only; registered as the CTest test Docs.LinksResolve.
"""
import os
import re
import sys
import unicodedata

README_LIMIT = 15360  # bytes: a user's guide, not a lab notebook (details live in docs/)
# The same pattern as `grep -rn "shared/docs\|METHOD.md\|EVALUATION.md"`: documents a clone of
# this repository does not have.
OUTSIDE_DOCS = re.compile(r"shared/docs|METHOD.md|EVALUATION.md")
OUTSIDE_DOCS_SUFFIXES = (".h", ".cc", ".md")
SKIPPED_DIRS = {".git", "out", "node_modules", "__pycache__", ".cache"}

FENCE = re.compile(r"^\s*(```|~~~)")
INLINE_CODE = re.compile(r"(`+)(?:.+?)\1")
# [text](target) and ![alt](target); target up to the first space or ')' (titles are ignored).
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE_DEF = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$")
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"")


def is_skipped_dir(name):
    return name in SKIPPED_DIRS or name.startswith("build")


def strip_code(lines):
    """Lines with fenced code blocks blanked and inline code spans removed (links there are text)."""
    out, fenced = [], False
    for line in lines:
        if FENCE.match(line):
            fenced = not fenced
            out.append("")
            continue
        out.append("" if fenced else INLINE_CODE.sub("", line))
    return out


def heading_text(raw):
    """The rendered text of a heading: links reduced to their text, code and emphasis marks gone."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", raw)
    return text.replace("`", "")


def github_slug(text):
    """GitHub's heading anchor: lowercase, every character that is not a letter, mark, decimal
    digit, connector punctuation (underscore), hyphen or space dropped, spaces turned into hyphens."""
    kept = []
    for ch in text.lower():
        cat = unicodedata.category(ch)
        if ch in "- " or cat[0] in "LM" or cat in ("Nd", "Pc"):
            kept.append(ch)
    return "".join(kept).replace(" ", "-")


def anchors_of(path, cache={}):
    if path not in cache:
        anchors, seen = set(), {}
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
        fenced = False
        for line in lines:
            if FENCE.match(line):
                fenced = not fenced
                continue
            if fenced:
                continue
            for name in HTML_ANCHOR.findall(line):
                anchors.add(name)
            m = HEADING.match(line)
            if not m:
                continue
            slug = github_slug(heading_text(m.group(2)))
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            anchors.add(slug if n == 0 else f"{slug}-{n}")
        cache[path] = anchors
    return cache[path]


def links_of(path):
    with open(path, encoding="utf-8") as f:
        lines = strip_code(f.read().splitlines())
    for number, line in enumerate(lines, 1):
        for target in INLINE_LINK.findall(line):
            yield number, target
        m = REFERENCE_DEF.match(line)
        if m:
            yield number, m.group(1)


def check_links(root, documents):
    problems = []
    root_real = os.path.realpath(root)
    for doc in documents:
        rel_doc = os.path.relpath(doc, root)
        for number, target in links_of(doc):
            if re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("//"):
                continue  # absolute URL (https:, mailto:, ...): not checked offline
            file_part, _, anchor = target.partition("#")
            if file_part:
                dest = os.path.normpath(os.path.join(os.path.dirname(doc), file_part))
            else:
                dest = doc
            where = f"{rel_doc}:{number}: link '{target}'"
            if not os.path.realpath(dest).startswith(root_real + os.sep) and \
                    os.path.realpath(dest) != root_real:
                problems.append(f"{where} points outside the repository")
                continue
            if not os.path.exists(dest):
                problems.append(f"{where}: {os.path.relpath(dest, root)} does not exist")
                continue
            if anchor:
                if not dest.endswith(".md") or os.path.isdir(dest):
                    problems.append(f"{where}: an #anchor into a file that is not Markdown")
                elif anchor not in anchors_of(dest):
                    problems.append(f"{where}: no heading with anchor '#{anchor}' in "
                                    f"{os.path.relpath(dest, root)}")
    return problems


def check_outside_docs(root):
    problems = []
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if not is_skipped_dir(d))
        for name in sorted(files):
            if not name.endswith(OUTSIDE_DOCS_SUFFIXES):
                continue
            path = os.path.join(folder, name)
            with open(path, encoding="utf-8", errors="replace") as f:
                for number, line in enumerate(f, 1):
                    if OUTSIDE_DOCS.search(line):
                        problems.append(f"{os.path.relpath(path, root)}:{number}: points outside the "
                                        f"repository ('{OUTSIDE_DOCS.search(line).group(0)}'); "
                                        "cite docs/method.md or docs/evaluation.md instead")
    return problems


def main(argv):
    root = os.path.abspath(argv[1] if len(argv) > 1 else
                           os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    readme = os.path.join(root, "README.md")
    docs = os.path.join(root, "docs")
    problems = []
    if not os.path.isfile(readme):
        problems.append("README.md is missing")
    else:
        size = os.path.getsize(readme)
        if size > README_LIMIT:
            problems.append(f"README.md is {size} bytes, more than {README_LIMIT}: move detail to docs/")
    documents = [readme] if os.path.isfile(readme) else []
    if os.path.isdir(docs):
        documents += sorted(os.path.join(docs, n) for n in os.listdir(docs) if n.endswith(".md"))
    else:
        problems.append("docs/ is missing")
    problems += check_links(root, documents)
    problems += check_outside_docs(root)
    for p in problems:
        print(p)
    readme_size = os.path.getsize(readme) if os.path.isfile(readme) else 0
    print(f"check_docs: README.md {readme_size} bytes (limit {README_LIMIT}), "
          f"{len(documents)} documents, {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
