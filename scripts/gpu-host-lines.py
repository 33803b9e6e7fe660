#!/usr/bin/env python3
"""Code lines of the GPU host code under src/algorithms/ (every wgpu.rs and raster.rs): lines
that hold code, not counting blank lines and comment-only lines (`//`, `///`, `//!`, and lines
inside `/* */`). Prints one line per file and the total; run from anywhere."""
import pathlib
import sys

root = pathlib.Path(__file__).resolve().parent.parent / "src" / "algorithms"
files = sorted(p for p in root.rglob("*.rs") if p.name in ("wgpu.rs", "raster.rs"))
if not files:
    sys.exit(f"error: no wgpu.rs or raster.rs under {root}")
total = 0
for path in files:
    code, in_block = 0, False
    for line in path.read_text().splitlines():
        s = line.strip()
        if in_block:
            if "*/" in s:
                in_block = False
                s = s.split("*/", 1)[1].strip()
            else:
                continue
        if s.startswith("/*"):
            in_block = "*/" not in s
            continue
        if s and not s.startswith("//"):
            code += 1
    total += code
    print(f"{code:6d}  {path.relative_to(root.parent.parent)}")
print(f"{total:6d}  GPU host code lines under src/algorithms/ (wgpu.rs and raster.rs)")
