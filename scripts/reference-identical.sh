#!/usr/bin/env bash
# The reference image of every built-in scene from two shadowbench binaries (say the commit
# before a change to the reference and after it), compared to the bit: visibility.npy of
# `shadowbench render --algorithm reference` at 160x120 and 64 samples (seed 1).
# Usage: scripts/reference-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR   (writes only under OUT_DIR)
set -euo pipefail
before=${1:?usage: scripts/reference-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR}
after=${2:?usage: scripts/reference-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR}
out=${3:?usage: scripts/reference-identical.sh BEFORE_BIN AFTER_BIN OUT_DIR}
mkdir -p "$out"
scenes=$("$after" list 2>/dev/null | awk '/^scenes/{s=1; next} /^[a-z]/{s=0} s && NF {print $1}')
[ -n "$scenes" ] || { echo "no scenes listed by $after list" >&2; exit 1; }
differ=0
for s in $scenes; do
  for side in before after; do
    bin=$before; [ "$side" = after ] && bin=$after
    "$bin" render --scene "$s" --algorithm reference --image 160x120 --samples 64 --seed 1 \
      --out "$out/$side/$s" >/dev/null 2>&1
  done
  if cmp -s "$out/before/$s/visibility.npy" "$out/after/$s/visibility.npy"; then
    echo "$s: identical"
  else
    echo "$s: DIFFERENT"; differ=1
  fi
done
exit $differ
