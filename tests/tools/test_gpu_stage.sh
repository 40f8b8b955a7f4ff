#!/bin/bash
# tools/models/gpu_stage.sh slim / restore touch the user's git index and .git/info/exclude: slim takes the large folders out
# of the index without deleting a file, refuses to run twice or over staged changes, and restore gives back the index
# and the exclude file exactly as they were (its earlier lines kept). Run in a throwaway repository.
#   test_gpu_stage.sh REPO
set -uo pipefail
top=$(mktemp -d)
trap 'rm -rf "$top"' EXIT
mkdir "$top/repo" && cd "$top/repo" || exit 1
git init -q . && git config user.email t@t && git config user.name t
mkdir -p tools/models resources/models docs/research/models docs/images resources/examples core
cp "$1/tools/models/gpu_stage.sh" tools/models/
for f in resources/models/m.safetensors docs/research/models/w.csv docs/images/i.png resources/examples/e.exr core/a.cpp; do
  echo "$f" > "$f"
done
git add -A && git commit -qm start
printf '%s\n' '# the user own' '*.tmp' > .git/info/exclude
cp .git/info/exclude "$top/exclude.before"
git ls-files > "$top/index.before"
fail=0

out=$(tools/models/gpu_stage.sh slim 2>&1) || { echo "FAIL: slim: $out"; fail=1; }
[ "$(git ls-files)" = "$(printf '%s\n' core/a.cpp tools/models/gpu_stage.sh)" ] ||
  { echo "FAIL: after slim the index holds: $(git ls-files | tr '\n' ' ')"; fail=1; }
[ -z "$(git status --porcelain --untracked-files=all | grep '^??')" ] ||
  { echo "FAIL: the slimmed folders show as untracked, so a call would send them"; fail=1; }
[ -f resources/models/m.safetensors ] && [ -f docs/images/i.png ] || { echo "FAIL: slim deleted files"; fail=1; }
out=$(tools/models/gpu_stage.sh slim 2>&1) && { echo "FAIL: a second slim ran: $out"; fail=1; }

out=$(tools/models/gpu_stage.sh restore 2>&1) || { echo "FAIL: restore: $out"; fail=1; }
git ls-files | cmp -s - "$top/index.before" || { echo "FAIL: the index differs after restore"; fail=1; }
cmp -s .git/info/exclude "$top/exclude.before" || { echo "FAIL: .git/info/exclude differs: $(cat .git/info/exclude)"; fail=1; }
[ -z "$(git status --porcelain --untracked-files=no)" ] || { echo "FAIL: changes after restore: $(git status -s)"; fail=1; }

echo change >> core/a.cpp && git add core/a.cpp
out=$(tools/models/gpu_stage.sh slim 2>&1) && { echo "FAIL: slim ran over a staged change: $out"; fail=1; }
grep -q "staged changes" <<< "$out" || { echo "FAIL: the refusal does not say why: $out"; fail=1; }
[ "$(git diff --cached --name-only)" = core/a.cpp ] || { echo "FAIL: the staged change was touched"; fail=1; }

[ "$fail" = 0 ] && echo ok
exit "$fail"
