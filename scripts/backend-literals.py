#!/usr/bin/env python3
"""Execution-name string literals ("cpu-native", "cpu-model", "wgpu") in the code under src/,
outside src/backend.rs (where the names are defined), `#[cfg(test)] mod tests` and comments.
Prints each with its place and the count; the names belong to `Backend`."""
import pathlib
import re

NAME = re.compile(r'"(cpu-native|cpu-model|wgpu)"')
total = 0
for path in sorted(pathlib.Path("src").rglob("*.rs")):
    if path.as_posix() == "src/backend.rs":
        continue
    text = path.read_text()
    cut = text.find("#[cfg(test)]\nmod tests")
    if cut >= 0:
        text = text[:cut]
    for number, line in enumerate(text.splitlines(), 1):
        code = line.strip()
        if code.startswith("//"):
            continue
        if NAME.search(code):
            total += 1
            print(f"  {path}:{number}: {code[:100]}")
print(f"{total:>6}  execution-name literals outside src/backend.rs, tests and comments")
