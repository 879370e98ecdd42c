#!/usr/bin/env python3
"""Static worst-case stack depth of the tasks of a Cortex-M (Thumb-2) ELF.

usage: stack-depth.py <elf> <root symbol>...   (e.g. CONTROL_TIMER LINK_SERVICE WORKER UART_RX main)
       stack-depth.py <elf> --nested <level> <level>...
         each level a comma-separated list of the roots of one priority, lowest first
         (e.g. main:frame LINK_SERVICE,WORKER UART_TX CONTROL_TIMER UART_RX; `name:frame` counts only
         that function's own frame: thread mode idles in main's frame after init
         returned): the worst case with every level
         preempting the one below (one shared stack, as RTIC runs): the deepest root of
         each level, plus an exception frame with FP context (26 words, 104 bytes, the
         Cortex-M4F's extended frame) for every level above the first.

From `arm-none-eabi-objdump -d`: each function's frame is what its push/stmdb, vpush
and `sub sp` reserve; its callees are the direct calls and tail branches (bl, b.w, b)
to other functions. The depth of a root is its frame plus the deepest callee chain
(recursion cut at the first repeat). Indirect calls (blx to a register) are not
followed. Prints the depth and the deepest chain of each root. A bound to read next
to the painted-stack measurement, not a replacement for it.
"""
import functools
import re
import subprocess
import sys


def parse(elf):
    dis = subprocess.run(
        ["arm-none-eabi-objdump", "-d", "-C", "--no-show-raw-insn", elf],
        check=True, capture_output=True, text=True).stdout
    funcs, cur = {}, None
    for line in dis.splitlines():
        m = re.match(r"^[0-9a-f]+ <(.*)>:$", line)
        if m:
            cur = m.group(1)
            funcs[cur] = {"frame": 0, "calls": set()}
            continue
        if cur is None:
            continue
        f = funcs[cur]
        m = re.search(r"\s(?:push(?:\.w)?|stmdb(?:\.w)?\s+sp!,)\s*\{([^}]*)\}", line)
        if m:
            f["frame"] += 4 * count_regs(m.group(1))
        m = re.search(r"\svpush\s*\{([^}]*)\}", line)
        if m:
            width = 8 if m.group(1).strip().startswith("d") else 4
            f["frame"] += width * count_regs(m.group(1))
        m = re.search(r"\ssub(?:\.w|w)?\s+sp, (?:sp, )?#(\d+)", line)
        if m:
            f["frame"] += int(m.group(1))
        m = re.search(r"\s(?:bl|blx|b\.w|b)\s+[0-9a-f]+ <(.*)>\s*$", line)
        if m and "+0x" not in m.group(1) and m.group(1) != cur:
            f["calls"].add(m.group(1))
    return funcs


# Bytes an exception entry pushes with an active FP context (Cortex-M4F extended frame:
# r0-r3, r12, lr, pc, xpsr, s0-s15, fpscr, reserved).
EXCEPTION_FRAME_FP_BYTES = 26 * 4


def count_regs(text):
    n = 0
    for r in text.split(","):
        r = r.strip()
        if "-" in r:
            a, b = r.split("-")
            n += int(b.strip()[1:]) - int(a.strip()[1:]) + 1
        elif r:
            n += 1
    return n


def main():
    funcs = parse(sys.argv[1])

    @functools.lru_cache(None)
    def depth(fn, seen):
        f = funcs.get(fn)
        if f is None:
            return 0, ()
        best, path = 0, ()
        for c in f["calls"]:
            if c in seen:
                continue
            d, p = depth(c, seen | {fn})
            if d > best:
                best, path = d, p
        return f["frame"] + best, ((fn, f["frame"]),) + path

    sys.setrecursionlimit(100000)
    if len(sys.argv) > 2 and sys.argv[2] == "--nested":
        total, parts = 0, []
        for k, level in enumerate(sys.argv[3:]):
            def level_depth(r):
                if r.endswith(":frame"):
                    return funcs.get(r[: -len(":frame")], {"frame": 0})["frame"]
                return depth(r, frozenset())[0]

            d, root = max((level_depth(r), r) for r in level.split(","))
            frame = EXCEPTION_FRAME_FP_BYTES if k > 0 else 0
            total += d + frame
            parts.append(f"{root} {d}" + (f" + {frame}" if frame else ""))
        print(f"NESTED depth_bytes={total} = " + " + ".join(parts))
        return
    for root in sys.argv[2:]:
        d, path = depth(root, frozenset())
        print(f"STATIC root={root} depth_bytes={d}")
        for fn, frame in path:
            print(f"    {frame:6d}  {fn[:100]}")


if __name__ == "__main__":
    main()
