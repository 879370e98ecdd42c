#!/usr/bin/env bash
# Builds m2ctl's QEMU instruction-counting plugin into target/qemu-insncount/ (gcc) and
# prints the path of the shared object. Rebuilds only when the source is newer.
set -euo pipefail
src=$(cd "$(dirname "$0")" && pwd)
out=$(cd "$src/../.." && pwd)/target/qemu-insncount
so=$out/libinsncount.so
mkdir -p "$out"
if [ ! -f "$so" ] || [ "$src/insncount.c" -nt "$so" ] || [ "$src/qemu_plugin_api.h" -nt "$so" ]; then
  gcc -std=c11 -O2 -Wall -Wextra -Werror -fPIC -shared -fvisibility=hidden \
    -o "$so.tmp" "$src/insncount.c"
  mv "$so.tmp" "$so"
fi
echo "$so"
