#!/usr/bin/env python3
"""Checks the documentation for what goes stale or breaks silently (issue 42):

- README.md has at most 250 lines and names no commit hash (7 to 40 hex digits, not all decimal);
- docs/index.md links every page of docs/, and every page it links exists;
- every relative link in README.md and docs/*.md (markdown links and <img src>) points to an
  existing file, and a #anchor into a markdown file to one of its headings;
- every key of every config/*.toml appears in docs/configuration.md as `key`, and every table as
  `[table]`, in the section of its file (the part under a heading that names `config/FILE.toml`).

  tests/docs/check_docs.py [REPO_ROOT] [--readme FILE]

REPO_ROOT defaults to the repository this script is in; --readme checks another README in place
of REPO_ROOT/README.md (its links are still resolved from REPO_ROOT). Prints what it checked;
exits 1 with every failure named."""
import os
import re
import sys

try:
    import tomllib
except ImportError:  # Python < 3.11
    try:
        import tomli as tomllib
    except ImportError:
        tomllib = None

README_MAX_LINES = 250
HASH = re.compile(r"\b[0-9a-f]{7,40}\b")
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
IMG = re.compile(r"<img\s[^>]*src=\"([^\"]+)\"")
FENCE = re.compile(r"^(```|~~~).*?^\1\s*$", re.M | re.S)
CODE_SPAN = re.compile(r"`[^`\n]*`")

failures = []
checked = []


def fail(what):
    failures.append(what)


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def prose(text):
    """The text without fenced code blocks and code spans: links there are not links."""
    return CODE_SPAN.sub("", FENCE.sub("", text))


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"<[^>]+>", "", heading.strip().lower())
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(path):
    seen, out = {}, set()
    for line in FENCE.sub("", read(path)).splitlines():
        m = re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        s = slug(m.group(1))
        n = seen.get(s, 0)
        seen[s] = n + 1
        out.add(s if n == 0 else f"{s}-{n}")
    return out


def links(path, text=None):
    """(target, line number) of every relative link in a markdown file."""
    text = read(path) if text is None else text
    body = prose(text)
    found = []
    for pattern in (LINK, IMG):
        for m in pattern.finditer(body):
            target = m.group(1)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # http:, https:, mailto:, file:
                continue
            found.append((target, body.count("\n", 0, m.start()) + 1))
    return found


def check_links(path, base_dir, text, root):
    shown = os.path.relpath(path, root)
    n = 0
    for target, line in links(path, text):
        n += 1
        file_part, _, anchor = target.partition("#")
        dest = os.path.normpath(os.path.join(base_dir, file_part)) if file_part else path
        if file_part and not os.path.exists(dest):
            fail(f"{shown}:{line}: link to '{target}': {os.path.relpath(dest, root)} does not exist")
            continue
        if anchor and dest.endswith(".md") and os.path.isfile(dest):
            if anchor not in anchors(dest):
                fail(f"{shown}:{line}: link to '{target}': {os.path.relpath(dest, root)} has no heading "
                     f"with the anchor #{anchor}")
    checked.append(f"{shown}: {n} relative links resolve")


def check_readme(root, readme_path):
    text = read(readme_path)
    shown = os.path.relpath(readme_path, root) if readme_path.startswith(root) else readme_path
    lines = text.count("\n") + (0 if text.endswith("\n") or not text else 1)
    if lines > README_MAX_LINES:
        fail(f"{shown}: {lines} lines, more than {README_MAX_LINES}: move detail to a page of docs/")
    else:
        checked.append(f"{shown}: {lines} lines (at most {README_MAX_LINES})")
    hashes = []
    for i, line in enumerate(text.splitlines(), 1):
        for m in HASH.finditer(line):
            if not m.group(0).isdigit():
                hashes.append(f"{shown}:{i}: '{m.group(0)}'")
    if hashes:
        fail(f"{shown}: names {len(hashes)} commit hash(es) (history goes to docs/history.md):\n    "
             + "\n    ".join(hashes))
    else:
        checked.append(f"{shown}: no commit hash")
    check_links(readme_path, root, text, root)


def check_index(root):
    docs = os.path.join(root, "docs")
    index = os.path.join(docs, "index.md")
    if not os.path.isfile(index):
        fail("docs/index.md does not exist")
        return
    linked = set()
    for target, line in links(index):
        file_part = target.partition("#")[0]
        if file_part:
            dest = os.path.normpath(os.path.join(docs, file_part))
            linked.add(dest)
            if not os.path.exists(dest):
                fail(f"docs/index.md:{line}: links '{target}', which does not exist")
    pages = sorted(p for p in os.listdir(docs) if p.endswith(".md") and p != "index.md")
    missing = [p for p in pages if os.path.join(docs, p) not in linked]
    if missing:
        fail("docs/index.md does not link these pages of docs/: " + ", ".join(missing))
    checked.append(f"docs/index.md links all {len(pages)} other pages of docs/")


def keys_of(table, prefix=""):
    """(tables, leaf keys) of a parsed TOML file: tables as '[name]' / '[[name]]', keys bare."""
    tables, keys = [], []
    for k, v in table.items():
        if isinstance(v, dict):
            tables.append(f"[{prefix}{k}]")
            t, ks = keys_of(v, f"{prefix}{k}.")
            tables += t
            keys += ks
        elif isinstance(v, list) and v and all(isinstance(e, dict) for e in v):
            tables.append(f"[[{prefix}{k}]]")
            for e in v:
                t, ks = keys_of(e, f"{prefix}{k}.")
                tables += t
                keys += ks
        else:
            keys.append(k)
    return tables, keys


def section(doc, filename):
    """The part of the reference under the heading naming config/FILENAME, to the next heading
    of the same or a higher level."""
    lines = doc.splitlines()
    for i, line in enumerate(lines):
        m = re.match(r"^(#{1,6})\s", line)
        if m and f"config/{filename}" in line:
            level = len(m.group(1))
            end = next((j for j in range(i + 1, len(lines))
                        if re.match(r"^#{1,%d}\s" % level, lines[j])), len(lines))
            return "\n".join(lines[i:end])
    return None


def check_configuration(root):
    if tomllib is None:
        fail("no TOML reader: Python 3.11's tomllib, or the tomli module, is needed")
        return
    ref_path = os.path.join(root, "docs", "configuration.md")
    if not os.path.isfile(ref_path):
        fail("docs/configuration.md does not exist")
        return
    doc = read(ref_path)
    config = os.path.join(root, "config")
    files = sorted(f for f in os.listdir(config) if f.endswith(".toml"))
    total = 0
    for name in files:
        with open(os.path.join(config, name), "rb") as f:
            data = tomllib.load(f)
        tables, keys = keys_of(data)
        part = section(doc, name)
        if part is None:
            fail(f"docs/configuration.md has no heading naming config/{name}")
            continue
        spans = set(re.findall(r"`([^`\n]+)`", part))
        missing = [t for t in dict.fromkeys(tables) if t not in spans]
        missing += [k for k in dict.fromkeys(keys) if k not in spans]
        if missing:
            fail(f"docs/configuration.md, section of config/{name}: missing "
                 + ", ".join(f"`{m}`" for m in missing))
        total += len(set(tables)) + len(set(keys))
    checked.append(f"docs/configuration.md: the {total} tables and keys of {len(files)} config/*.toml files "
                   "each in their file's section")


def main(argv):
    args = argv[1:]
    readme = None
    if "--readme" in args:
        i = args.index("--readme")
        readme = os.path.abspath(args[i + 1])
        del args[i:i + 2]
    root = os.path.abspath(args[0] if args else os.path.join(os.path.dirname(__file__), "..", ".."))
    readme = readme or os.path.join(root, "README.md")
    check_readme(root, readme)
    check_index(root)
    docs = os.path.join(root, "docs")
    for page in sorted(p for p in os.listdir(docs) if p.endswith(".md")):
        path = os.path.join(docs, page)
        check_links(path, docs, read(path), root)
    check_configuration(root)
    for line in checked:
        print("checked " + line)
    if failures:
        print(f"\ndocs_check: {len(failures)} failure(s):", file=sys.stderr)
        for f in failures:
            print("  " + f, file=sys.stderr)
        return 1
    print("docs_check: all passed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
