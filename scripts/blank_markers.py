#!/usr/bin/python3
"""Writes a copy of a TRC with markers blanked (missing) over frame ranges, to measure how gaps
are filled and solved against the full trial (docs/gap-filling.md, docs/angles.md "Gaps").

  /usr/bin/python3 scripts/blank_markers.py IN.trc OUT.trc MARKER:FIRST-LAST [...]

FIRST and LAST are the file's frame numbers (Frame#), both blanked; MARKER '*' is every marker.
Example: scripts/blank_markers.py walk1.trc gaps.trc R.ASIS:21-80 'R.Wrist.Med:1-60' '*:70-75'
"""
import sys


def parse_gap(text):
    marker, _, frames = text.rpartition(":")
    first, _, last = frames.partition("-")
    if not marker or not first.isdigit() or not last.isdigit() or int(first) > int(last):
        sys.exit(f"'{text}': expected MARKER:FIRST-LAST (frame numbers, FIRST <= LAST)")
    return marker, int(first), int(last)


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    source, target, gaps = sys.argv[1], sys.argv[2], [parse_gap(g) for g in sys.argv[3:]]
    with open(source, newline="") as f:
        lines = f.read().splitlines()
    if len(lines) < 6 or not lines[0].startswith("PathFileType"):
        sys.exit(f"{source}: not a TRC file")
    names = [n.strip() for n in lines[3].split("\t")[2::3]]
    names = [n for n in names if n]
    columns = {}
    for marker, first, last in gaps:
        chosen = names if marker == "*" else [marker]
        for name in chosen:
            if name not in names:
                sys.exit(f"{source}: no marker '{name}' (markers: {', '.join(names)})")
            columns.setdefault(names.index(name), []).append((first, last))
    out = lines[:5]
    for line in lines[5:]:
        cells = line.split("\t")
        if not line.strip() or not cells[0].strip():
            out.append(line)
            continue
        frame = int(float(cells[0]))
        for m, ranges in columns.items():
            if any(first <= frame <= last for first, last in ranges):
                for k in range(2 + 3 * m, min(5 + 3 * m, len(cells))):
                    cells[k] = ""
        out.append("\t".join(cells))
    with open(target, "w", newline="") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
