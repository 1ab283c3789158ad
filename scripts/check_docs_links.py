#!/usr/bin/python3
"""Fails when a relative link in README.md, docs/ or proto/ leads nowhere.

Usage: check_docs_links.py [REPO_ROOT]. Checks every Markdown link and image
`[text](target)` outside code: the target file must exist, and a `#fragment`
must name a heading of the target page (GitHub's anchors). Web links are not
followed, and links out of the repository (`../shared/...`) are not checked:
neither is ours to keep. Exit 1 with one line per broken link, else 0.
"""
import pathlib
import re
import sys

# Pages that other branches of issue 23 write; linked before they land. A page
# here is checked like any other once it exists.
PENDING = {"docs/embedding.md", "docs/python.md", "docs/batch.md"}

LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
INLINE_CODE = re.compile(r"(`+)(?:(?!\1).)*?\1")


def prose_lines(text):
    """(line number, line) outside fenced code, with inline code blanked."""
    fenced = False
    for number, line in enumerate(text.split("\n"), 1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            yield number, INLINE_CODE.sub(lambda m: " " * len(m.group(0)), line)


def slug(heading):
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to '-'."""
    text = re.sub(r"`", "", heading).strip().lower()
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    seen = {}
    out = set()
    fenced = False
    for line in path.read_text(encoding="utf-8").split("\n"):
        if FENCE.match(line):
            fenced = not fenced
            continue
        m = None if fenced else HEADING.match(line)
        if m:
            base = slug(m.group(2))
            n = seen.get(base, 0)
            seen[base] = n + 1
            out.add(base if n == 0 else f"{base}-{n}")
    return out


def pages(root):
    found = [root / "README.md"]
    found += sorted((root / "docs").rglob("*.md"))
    found += sorted((root / "proto").glob("*.md"))
    return [p for p in found if p.is_file()]


def check(root):
    root = root.resolve()
    broken = []
    checked = 0
    for page in pages(root):
        for number, line in prose_lines(page.read_text(encoding="utf-8")):
            for m in LINK.finditer(line):
                target = m.group(1)
                if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):
                    continue  # http:, https:, mailto:
                checked += 1
                where = f"{page.relative_to(root)}:{number}: {target}"
                path_part, _, fragment = target.partition("#")
                dest = page if not path_part else (page.parent / path_part).resolve()
                try:
                    rel = dest.relative_to(root).as_posix()
                except ValueError:
                    continue  # out of the repository
                if not dest.exists():
                    if rel not in PENDING:
                        broken.append(f"{where}: no such file")
                    continue
                if fragment and dest.suffix == ".md" and fragment not in anchors(dest):
                    broken.append(f"{where}: no heading with anchor '#{fragment}' in {rel}")
    return broken, checked


def main():
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parent.parent)
    broken, checked = check(root)
    for b in broken:
        print(b)
    print(f"check_docs_links: {len(broken)} broken of {checked} relative links in {len(pages(root))} pages")
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
