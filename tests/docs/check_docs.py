#!/usr/bin/env python3
"""The docs read as a reference (issue 26, item 4): for docs/*.md and README.md

  - no paragraph over 600 characters of Markdown source (a paragraph is a block
    separated by blank lines; each list item counts on its own; headings,
    tables, fenced and indented code blocks are not paragraphs);
  - no mention of CI runs ("CI run", "CI rehearsal", "CI of stop 22",
    "stop 22", "run #12"): history belongs in commit messages;
  - no ISO date (2026-12-02) in prose: dates of debugging are history too;
  - every relative link ([text](page.md)) and every repository path written
    outside code blocks (`messages/src/csv.cpp`, docs/time.md) exists in the
    tree. A path
    counts when its first component is a top-level entry of the repository
    (build*/ outputs excepted); paths with placeholders (<name>, *, ...) are
    not checked.

  check_docs.py SOURCE_DIR     check the tree (pages in EXEMPT are skipped)
  check_docs.py --self-test    check the checker on planted violations

Exit 0: clean; 1: findings (one line each, file:line: what); 2: usage.
"""
import os
import re
import sys
import tempfile

LIMIT = 600

# Pages still being rewritten as a reference. THIS LIST MUST SHRINK TO EMPTY:
# whoever rewrites a page removes it here in the same commit. A listed page
# that passes every check, or that no longer exists, fails the test, so the
# list cannot go stale.
EXEMPT = []

# A CI run as a thing that happened ("the CI run", "two CI runs", "CI run 12"),
# not CI as the one that runs something ("what CI runs").
CI_PATTERNS = [
    re.compile(r"\b(?:a|an|the|one|two|three|four|five|\d+|this|that|its|first|last|several|"
               r"some|many|each|which|earlier|later|failed|failing)\s+CI\s+(?:runs?|jobs?)\b",
               re.I),
    re.compile(r"\bCI\s+(?:runs?|jobs?)\s*(?:#|no\.?\s*)?\d+"),
    re.compile(r"\bCI\s+runs?\s+(?:of|on|that|where|in which)\b"),
    re.compile(r"\bCI\s+rehearsals?\b"),
    re.compile(r"\bCI\s+of\s+stop\b"),
    re.compile(r"\bCI\s*#\d+"),
    re.compile(r"\bstop\s+\d+\b"),
    re.compile(r"\bruns?\s+#\d+", re.I),
]
DATE = re.compile(r"\b(?:19|20)\d\d-(?:0[1-9]|1[0-2])-(?:0[1-9]|[12]\d|3[01])\b")
LIST_ITEM = re.compile(r"^\s*(?:[-*+]|\d+[.)])\s+")
FENCE = re.compile(r"^\s*(```|~~~)")
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
INLINE_CODE = re.compile(r"`[^`]*`")
PATH = re.compile(r"(?<![\w./~$<>-])((?:\.[\w-]+|[\w-]+)(?:/[\w.+-]+)+/?)")


def blocks(lines):
    """Yields (kind, first line number, [lines]) for each block of a page:
    kind is 'code', 'table', 'heading' or 'prose' (one per paragraph or list
    item)."""
    i, n = 0, len(lines)
    previous_was_list = False
    while i < n:
        line = lines[i]
        if not line.strip():
            i += 1
            continue
        if FENCE.match(line):
            start, fence = i, FENCE.match(line).group(1)
            i += 1
            while i < n and not lines[i].lstrip().startswith(fence):
                i += 1
            i += 1
            yield "code", start + 1, lines[start:i]
            continue
        start = i
        while i < n and lines[i].strip() and not FENCE.match(lines[i]):
            i += 1
        block = lines[start:i]
        if all(b.lstrip().startswith("|") for b in block):
            yield "table", start + 1, block
            continue
        indented = all(b.startswith("    ") or b.startswith("\t") for b in block)
        if indented and not previous_was_list:
            yield "code", start + 1, block
            continue
        is_list = False
        item, item_start = [], start
        for k, b in enumerate(block):
            if b.lstrip().startswith("#") and not item:
                yield "heading", start + k + 1, [b]
                continue
            if LIST_ITEM.match(b) or b.lstrip().startswith("|"):
                if item:
                    yield "prose", item_start + 1, item
                item, item_start = [b], start + k
                is_list = is_list or bool(LIST_ITEM.match(b))
            else:
                if not item:
                    item_start = start + k
                item.append(b)
        if item:
            yield "prose", item_start + 1, item
        previous_was_list = is_list or (indented and previous_was_list)


def top_level(root):
    return {e for e in os.listdir(root) if not e.startswith("build")}


def path_exists(root, path):
    return os.path.exists(os.path.join(root, path.rstrip("/")))


def candidate_paths(text, tops):
    for m in PATH.finditer(text):
        p = m.group(1).rstrip(".,;:")
        if p.split("/", 1)[0] not in tops:
            continue
        if re.search(r"[*<>{}]|\.\.\.|…", p):
            continue
        yield p


def check_page(root, rel):
    """Findings of one page: a list of 'file:line: what'."""
    full = os.path.join(root, rel)
    with open(full, encoding="utf-8") as f:
        lines = f.read().split("\n")
    tops = top_level(root)
    out = []
    for kind, line, block in blocks(lines):
        text = " ".join(b.strip() for b in block)
        where = "%s:%d" % (rel, line)
        if kind == "prose" and len(text) > LIMIT:
            out.append("%s: paragraph of %d characters (at most %d): \"%s...\""
                       % (where, len(text), LIMIT, text[:60]))
        if kind != "code":
            for pattern in CI_PATTERNS:
                m = pattern.search(text)
                if m:
                    out.append("%s: mentions a CI run (\"%s\"): history belongs in git"
                               % (where, m.group(0)))
        if kind in ("prose", "heading"):
            m = DATE.search(INLINE_CODE.sub("", text))
            if m:
                out.append("%s: date %s in prose: history belongs in git" % (where, m.group(0)))
        if kind != "code":
            for m in LINK.finditer(INLINE_CODE.sub("", text)):
                target = m.group(1).split("#", 1)[0]
                if not target or re.match(r"^[a-z][a-z0-9+.-]*:", target):
                    continue
                resolved = os.path.normpath(os.path.join(os.path.dirname(rel), target))
                if not path_exists(root, resolved):
                    out.append("%s: link to %s, which does not exist" % (where, target))
        if kind != "code":
            for p in candidate_paths(text, tops):
                if not path_exists(root, p):
                    out.append("%s: %s does not exist in the tree" % (where, p))
    return out


def pages(root):
    docs = os.path.join(root, "docs")
    names = sorted("docs/" + f for f in os.listdir(docs) if f.endswith(".md"))
    if os.path.exists(os.path.join(root, "README.md")):
        names.append("README.md")
    return names


def check_tree(root, exempt):
    """(findings, notes): findings fail the test."""
    findings = []
    all_pages = pages(root)
    for rel in exempt:
        if rel not in all_pages:
            findings.append("%s: listed in EXEMPT but no such page: remove it from the list" % rel)
    checked = 0
    for rel in all_pages:
        found = check_page(root, rel)
        if rel in exempt:
            if not found:
                findings.append("%s: passes every check now: remove it from EXEMPT "
                                "(tests/docs/check_docs.py)" % rel)
            continue
        checked += 1
        findings.extend(found)
    return findings, checked


def self_test():
    """Plants one violation of each kind and checks that each is found where
    it is, and that a clean page and an exemption behave."""
    long_text = " ".join(["word"] * 130)  # 649 characters
    clean = "\n".join([
        "# A clean page",
        "",
        "A short paragraph (what CI runs: `.ci/run`) that links to [itself](clean.md#a-clean-page)",
        "[the web](https://example.org/x/y), and names `docs/clean.md`, src/real.cpp,",
        "`f(x)[a](b)` in code and `src/` (a directory)",
        "and `exodaq/include/path.hpp` (an include path, not a repository path).",
        "",
        "| a table row may be long | " + long_text + " | 2026-12-02 |",
        "|---|---|---|",
        "",
        "```",
        long_text + " 2026-12-02 src/not_here.cpp CI run 12",
        "```",
        "",
        "    indented code: " + long_text,
        "",
        "- a short item",
        "- another short item, placeholders src/<name>/x.cpp and src/*.cpp",
        "",
    ])
    bad = "\n".join([
        "# A bad page",                                      # 1
        "",                                                  # 2
        long_text,                                           # 3
        "",                                                  # 4
        "- short",                                           # 5
        "- " + long_text,                                    # 6
        "",                                                  # 7
        "It failed in the CI run of that day; what CI runs is fine.",  # 8
        "",                                                  # 9
        "The CI of stop 22 saw it.",                         # 10
        "",                                                  # 11
        "Fixed by run #45 and again in run #46.",            # 12
        "",                                                  # 13
        "Both refinements date from 2026-12-02.",            # 14
        "",                                                  # 15
        "See [the missing page](missing.md).",               # 16
        "",                                                  # 17
        "Fields are named in `src/fields.cpp`.",             # 18
        "",                                                  # 19
        "    a code block after a list is code: " + long_text,  # 20
        "",
    ])
    expected = {
        3: "paragraph of 649",
        6: "paragraph of 651",
        8: "mentions a CI run",
        10: "mentions a CI run",
        12: "mentions a CI run",
        14: "date 2026-12-02",
        16: "link to missing.md",
        18: "src/fields.cpp does not exist",
    }
    problems = []
    with tempfile.TemporaryDirectory() as root:
        os.makedirs(os.path.join(root, "docs"))
        os.makedirs(os.path.join(root, "src"))
        open(os.path.join(root, "src", "real.cpp"), "w").close()
        for name, text in (("clean.md", clean), ("bad.md", bad)):
            with open(os.path.join(root, "docs", name), "w", encoding="utf-8") as f:
                f.write(text)
        found_clean = check_page(root, "docs/clean.md")
        if found_clean:
            problems.append("a clean page has findings:\n    " + "\n    ".join(found_clean))
        found_bad = check_page(root, "docs/bad.md")
        for line, what in expected.items():
            if not any(f.startswith("docs/bad.md:%d:" % line) and what in f for f in found_bad):
                problems.append("planted violation not found: line %d, %s" % (line, what))
        unexpected = [f for f in found_bad
                      if int(f.split(":")[1]) not in expected]
        if unexpected:
            problems.append("findings where nothing was planted:\n    " + "\n    ".join(unexpected))
        # The tree check: a bad page fails, an exempt clean page must leave the
        # list, a stale exemption fails, a passing exemption-free tree passes.
        findings, _ = check_tree(root, [])
        if not any(f.startswith("docs/bad.md") for f in findings):
            problems.append("check_tree does not fail on the bad page")
        findings, _ = check_tree(root, ["docs/bad.md", "docs/clean.md", "docs/gone.md"])
        if not any("docs/clean.md: passes every check now" in f for f in findings):
            problems.append("an exempt page that passes is not reported")
        if not any("docs/gone.md: listed in EXEMPT but no such page" in f for f in findings):
            problems.append("a stale exemption is not reported")
        if any(f.startswith("docs/bad.md:") for f in findings):
            problems.append("an exempt page's findings fail the tree")
        os.remove(os.path.join(root, "docs", "bad.md"))
        findings, checked = check_tree(root, [])
        if findings or checked != 1:
            problems.append("a clean tree fails: %s" % findings)
    if problems:
        print("check_docs self-test FAILED:\n  " + "\n  ".join(problems), file=sys.stderr)
        return 1
    print("check_docs self-test: %d planted violations found, clean page and exemptions "
          "behave" % len(expected))
    return 0


def main(argv):
    if len(argv) == 2 and argv[1] == "--self-test":
        return self_test()
    if len(argv) != 2 or not os.path.isdir(os.path.join(argv[1], "docs")):
        print(__doc__, file=sys.stderr)
        return 2
    findings, checked = check_tree(argv[1], EXEMPT)
    if findings:
        print("\n".join(findings), file=sys.stderr)
        print("check_docs: %d finding(s)" % len(findings), file=sys.stderr)
        return 1
    print("check_docs: %d pages clean (%d still exempt: %s)"
          % (checked, len(EXEMPT), ", ".join(EXEMPT)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
