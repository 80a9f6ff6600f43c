#!/usr/bin/env python3
"""Checks the documentation: README.md stays a short user's guide, every relative link in
README.md and docs/*.md resolves inside the repository (files and #anchors), no source or
document points at design documents outside the repository, and every number in a row of the
README's headline table appears verbatim in the page section(s) that row links to (a figure lives
in one place; the README quotes it and links there, so a copy that drifts is caught).

Usage:
  scripts/check_docs.py [REPOSITORY_ROOT]            the checks above (CTest Docs.LinksResolve)
  scripts/check_docs.py --self-test [REPOSITORY_ROOT]
      copies README.md and docs/ to a temporary folder, changes one headline number in the README
      and, separately, in the page it links to, and fails unless the headline check catches both
      (CTest Docs.DetectsPlantedMismatch)
  scripts/check_docs.py --cli BODYMODEL_EXE [REPOSITORY_ROOT]
      runs `bodymodel --help` and every verb's `--help`: every verb must have a section in
      docs/cli.md (a heading naming it, e.g. "## skin eval" or "## encode, decode, interpolate")
      and every --option its help lists must be mentioned in that section (CTest Docs.CliMatchesHelp)
(REPOSITORY_ROOT defaults to the folder above this script.)
Exit status 0 when every check passes, 1 otherwise (each problem printed on its own line).
Python 3 standard library only.
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile
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


# ---- the README's headline table against the pages it links to ------------------------------

HEADLINE_HEADING = "Headline results"
# Digit groups of a thousands-separated number ("1 632", "13 380"; space, no-break or thin space)
# are joined before numbers are compared, on both sides.
THOUSANDS = re.compile(r"(?<=\d)[ \u00a0\u2009\u202f](?=\d{3}(?!\d))")
# A number: not glued to a word on either side ("p95", "hm08", "2σ", "s000_p0" are names).
# "160..180" is two numbers; "4.51" one.
NUMBER = re.compile(r"(?<!\w)(?<!\d\.)\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w]|\.\d)")
LINK_TARGET = re.compile(r"(!?\[(?:[^\[\]]|\[[^\]]*\])*\])\(\s*<?[^)\s>]+>?(?:\s+\"[^\"]*\")?\s*\)")


def numbers_in(text):
    return NUMBER.findall(THOUSANDS.sub("", text))


def section_of(path, anchor):
    """The text of the page (anchor empty) or of the section under the heading (or <a name>) with
    that anchor, down to the next heading of the same or a higher level; None if there is none."""
    with open(path, encoding="utf-8") as f:
        lines = f.read().splitlines()
    if not anchor:
        return "\n".join(lines)
    seen, fenced, start, level = {}, False, None, 0
    for i, line in enumerate(lines):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if fenced:
            continue
        m = HEADING.match(line)
        if start is not None:
            if m and len(m.group(1)) <= level:
                return "\n".join(lines[start:i])
            continue
        if anchor in HTML_ANCHOR.findall(line):
            start, level = i, 6
            continue
        if m:
            slug = github_slug(heading_text(m.group(2)))
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            if (slug if n == 0 else f"{slug}-{n}") == anchor:
                start, level = i, len(m.group(1))
    return None if start is None else "\n".join(lines[start:])


def headline_rows(readme):
    """(line number, row text) of each body row of the first table under '## Headline results'."""
    with open(readme, encoding="utf-8") as f:
        lines = f.read().splitlines()
    rows, inside, seen_table = [], False, False
    for number, line in enumerate(lines, 1):
        m = HEADING.match(line)
        if m:
            if inside:
                break
            inside = heading_text(m.group(2)) == HEADLINE_HEADING
            continue
        if not inside:
            continue
        if line.lstrip().startswith("|"):
            seen_table = True
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if all(re.fullmatch(r":?-+:?", c) for c in cells if c):
                continue
            rows.append((number, line))
        elif seen_table and line.strip():
            break
    return rows[1:]  # the first row is the header


def check_headline(root):
    """Every number in a headline row (links' targets aside) must appear verbatim in one of the
    page sections the row links to: the page is where the figure lives, the README quotes it."""
    readme = os.path.join(root, "README.md")
    problems = []
    if not os.path.isfile(readme):
        return problems
    rows = headline_rows(readme)
    if not rows:
        return [f"README.md: no table under '## {HEADLINE_HEADING}'"]
    for number, row in rows:
        targets = [t for t in INLINE_LINK.findall(row)
                   if not re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", t)]
        label = row.strip().strip("|").split("|")[0].strip()
        where = f"README.md:{number}: headline row '{label}'"
        if not targets:
            problems.append(f"{where} links to no page: link the page where its figures live")
            continue
        sections = []
        for target in targets:
            file_part, _, anchor = target.partition("#")
            dest = os.path.normpath(os.path.join(root, file_part)) if file_part else readme
            if not dest.endswith(".md") or not os.path.isfile(dest):
                continue  # check_links reports it
            text = section_of(dest, anchor)
            if text is not None:
                sections.append(text)
        found = set()
        for text in sections:
            found.update(numbers_in(text))
        missing = []
        for value in numbers_in(LINK_TARGET.sub(r"\1", row)):
            if value not in found and value not in missing:
                missing.append(value)
        if missing:
            problems.append(f"{where}: {', '.join(missing)} not found in "
                            f"{', '.join(targets)} (the page is the source: quote it, or fix it "
                            "there and here)")
    return problems


def self_test(root):
    """Plants a mismatch between the README's headline table and a page, in a copy, and checks
    that check_headline reports it (and does not report the unchanged copy)."""
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copy(os.path.join(root, "README.md"), tmp)
        shutil.copytree(os.path.join(root, "docs"), os.path.join(tmp, "docs"))
        baseline = check_headline(tmp)
        if baseline:
            failures.append("the unchanged copy already fails the headline check:")
            failures += ["  " + p for p in baseline]
            return failures
        readme = os.path.join(tmp, "README.md")
        with open(readme, encoding="utf-8") as f:
            original_readme = f.read()
        # The first decimal figure of the first headline row that has one, and its page.
        planted = None
        for number, row in headline_rows(readme):
            decimals = [v for v in numbers_in(LINK_TARGET.sub(r"\1", row)) if "." in v]
            targets = [t for t in INLINE_LINK.findall(row) if t.partition("#")[0].endswith(".md")]
            if decimals and targets:
                planted = (row, decimals[0], targets)
                break
        if planted is None:
            return ["no headline row with a decimal figure and a linked page to plant a mismatch in"]
        row, value, targets = planted
        # A value that appears nowhere in the linked pages, so the planted figure cannot match.
        pages_text = ""
        for target in targets:
            with open(os.path.join(tmp, target.partition("#")[0]), encoding="utf-8") as f:
                pages_text += f.read()
        present = set(numbers_in(pages_text)) | set(numbers_in(row))
        candidates = [value[:-1] + str(d) for d in range(10)] + [value + "97", value + "9797"]
        changed = next(c for c in candidates if c not in present)
        as_number = re.compile(r"(?<!\w)(?<!\d\.)" + re.escape(value) + r"(?![\w]|\.\d)")
        # 1. the README's copy changes, the page does not
        with open(readme, "w", encoding="utf-8") as f:
            f.write(original_readme.replace(row, as_number.sub(changed, row, count=1), 1))
        if not any(changed in p for p in check_headline(tmp)):
            failures.append(f"README figure {value} changed to {changed}: not detected")
        with open(readme, "w", encoding="utf-8") as f:
            f.write(original_readme)
        # 2. the page's figure changes (every occurrence in the linked pages), the README does not
        for target in targets:
            page = os.path.join(tmp, target.partition("#")[0])
            with open(page, encoding="utf-8") as f:
                text = f.read()
            with open(page, "w", encoding="utf-8") as f:
                f.write(as_number.sub(changed, text))
        if not any(value in p for p in check_headline(tmp)):
            failures.append(f"page figure {value} changed to {changed}: not detected")
        if not failures:
            print(f"self-test: planted {value} -> {changed} in README.md and in "
                  f"{', '.join(targets)}; both detected")
    return failures


# ---- docs/cli.md against every verb's --help -------------------------------------------------

HELP_OPTION = re.compile(r"^  (-[^\s,]+(?:,-[^\s,]+)*)")
LONG_OPTION = re.compile(r"--[A-Za-z0-9][\w-]*")


def run_help(exe, words):
    result = subprocess.run([exe, *words, "--help"], capture_output=True, text=True, timeout=60)
    if result.returncode != 0:
        raise RuntimeError(f"`bodymodel {' '.join(words + ['--help'])}` exited {result.returncode}: "
                           f"{result.stderr.strip()}")
    return result.stdout


def parse_help(text):
    """(subcommand names, long options) of one CLI11 --help text."""
    subcommands, options, in_subcommands, started = [], [], False, False
    for line in text.splitlines():
        if not started:  # the description comes first; options and subcommands follow "Usage:"
            started = line.startswith("Usage:")
            continue
        if re.match(r"^\S.*:\s*$", line):  # a group heading: "Options:", "Subcommands:", ...
            in_subcommands = line.strip().lower().startswith("subcommands")
            continue
        if in_subcommands:
            m = re.match(r"^  (\S+)", line)
            if m:
                subcommands.append(m.group(1))
            continue
        m = HELP_OPTION.match(line)
        if m:
            options += [o for o in LONG_OPTION.findall(m.group(1)) if o not in ("--help", "--version")]
    return subcommands, options


def cli_sections(cli_md):
    """{verb: section text} from docs/cli.md: a heading names one verb or several, comma-separated."""
    with open(cli_md, encoding="utf-8") as f:
        lines = f.read().splitlines()
    headings, fenced = [], False
    for i, line in enumerate(lines):
        if FENCE.match(line):
            fenced = not fenced
            continue
        m = None if fenced else HEADING.match(line)
        if m:
            headings.append((i, len(m.group(1)), heading_text(m.group(2))))
    sections = {}
    for k, (i, level, text) in enumerate(headings):
        end = next((j for j, lv, _ in headings[k + 1:] if lv <= level), len(lines))
        for name in text.split(","):
            sections.setdefault(name.strip(), "\n".join(lines[i:end]))
    return sections


def check_cli(exe, root):
    problems = []
    cli_md = os.path.join(root, "docs", "cli.md")
    sections = cli_sections(cli_md)
    verbs, pending = [], [[]]
    while pending:
        words = pending.pop(0)
        try:
            subcommands, options = parse_help(run_help(exe, words))
        except (OSError, RuntimeError, subprocess.TimeoutExpired) as e:
            problems.append(str(e))
            continue
        if subcommands:
            pending += [words + [s] for s in subcommands]
        elif words:
            verbs.append((" ".join(words), options))
    if not verbs:
        problems.append(f"`{exe} --help` lists no verbs")
    for verb, options in verbs:
        section = sections.get(verb)
        if section is None:
            problems.append(f"docs/cli.md: no section for `bodymodel {verb}` (a heading '## {verb}')")
            continue
        for option in options:
            if not re.search(re.escape(option) + r"(?![\w-])", section):
                problems.append(f"docs/cli.md: section '{verb}' does not mention {option} "
                                f"(listed by `bodymodel {verb} --help`)")
    print(f"check_docs --cli: {len(verbs)} verbs, "
          f"{sum(len(o) for _, o in verbs)} options checked against docs/cli.md")
    return problems


def main(argv):
    args = argv[1:]
    mode, exe = "docs", None
    if args[:1] == ["--self-test"]:
        mode, args = "self-test", args[1:]
    elif args[:1] == ["--cli"]:
        if len(args) < 2:
            print("usage: check_docs.py --cli BODYMODEL_EXE [REPOSITORY_ROOT]")
            return 2
        mode, exe, args = "cli", args[1], args[2:]
    root = os.path.abspath(args[0] if args else
                           os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    if mode != "docs":
        problems = self_test(root) if mode == "self-test" else check_cli(exe, root)
        for p in problems:
            print(p)
        print(f"check_docs --{mode}: {len(problems)} problem(s)")
        return 1 if problems else 0
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
    headline = check_headline(root)
    problems += headline
    for p in problems:
        print(p)
    readme_size = os.path.getsize(readme) if os.path.isfile(readme) else 0
    print(f"check_docs: README.md {readme_size} bytes (limit {README_LIMIT}), "
          f"{len(documents)} documents, {len(headline_rows(readme)) if os.path.isfile(readme) else 0} "
          f"headline rows, {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
