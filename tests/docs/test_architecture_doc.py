#!/usr/bin/python3
"""docs/ARCHITECTURE.md names only what exists: every path it gives (core/..., ui/..., tools/..., tests/...) is in the
tree, and every file it names (`denoiser.h`, `fuzz.sh`, ...) exists somewhere in it; and every module folder of core/
is described. Run by ctest (docs_architecture)."""
import os
import re
import sys

repo = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
text = open(os.path.join(repo, "docs", "ARCHITECTURE.md")).read()

names = set()
for root, dirs, files in os.walk(repo):
    dirs[:] = [d for d in dirs if d not in (".git", "build", ".cache", "node_modules")]
    names.update(files)

problems = []
for token in set(re.findall(r"`([^`\n]+)`", text)) | set(re.findall(r"(?<![\w./-])((?:core|ui|app|tools|tests|resources|packaging|docs)/[\w./-]+)", text)):
    t = token.strip().rstrip(".,;:)")
    if re.search(r"\b[A-Z]{3,}\b", t):  # a placeholder: resources/models/NAME.safetensors
        continue
    if re.fullmatch(r"(core|ui|app|tools|tests|resources|packaging|docs)/[\w./-]*", t):
        if not os.path.exists(os.path.join(repo, t)) and not os.path.exists(os.path.join(repo, t + ".h")):
            problems.append(f"path '{t}' does not exist")
    elif re.fullmatch(r"[\w-]+\.(h|cpp|py|sh|cmake|desktop)", t):
        if t not in names:
            problems.append(f"file '{t}' is named but no file of that name exists")

for module in sorted(os.listdir(os.path.join(repo, "core"))):
    if os.path.isdir(os.path.join(repo, "core", module)) and f"`core/{module}/`" not in text:
        problems.append(f"core/{module}/ has no row in the modules table")

for p in sorted(set(problems)):
    print("ARCHITECTURE.md:", p)
print(f"{len(set(problems))} problems" if problems else "ARCHITECTURE.md: every path and file it names exists")
sys.exit(1 if problems else 0)
