#!/usr/bin/env python3
"""The innermost loops of one function in a `--emit asm` file, ranked by fused multiply-adds, each
run through llvm-mca for the CPUs named: how the README's NEON speed estimate was made.

usage: mca_loops.py ASM FUNCTION_REGEX a64|x86 TOP CPU [CPU...]
"""
import re
import subprocess
import sys
import tempfile


def main():
    asm, func_re, arch, top, cpus = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5:]
    lines = open(asm).read().split("\n")
    start = next(i for i, l in enumerate(lines) if re.match(func_re, l))
    end = next(i for i in range(start, len(lines)) if lines[i].strip().startswith(".cfi_endproc"))
    body = lines[start:end]
    labels = {m.group(1): i for i, l in enumerate(body) if (m := re.match(r"^(\.LBB\w+):", l))}

    def instructions(i, j):
        return [t for t in (l.strip() for l in body[i:j + 1])
                if t and not t.endswith(":") and not t.startswith((".", "//", "#"))]

    # A loop: a label and a later branch back to it; innermost: no other loop inside.
    loops = []
    for j, l in enumerate(body):
        t = l.strip()
        for lab, i in labels.items():
            if i < j and re.search(r"[\s,]" + re.escape(lab) + r"$", t):
                loops.append((i, j, lab))
    inner = [(i, j, lab) for i, j, lab in loops if not any(i < a and b <= j for a, b, _ in loops if (a, b) != (i, j))]
    is_fma = (lambda t: t.startswith(("fmla", "fmls"))) if arch == "a64" else (lambda t: re.match(r"vfn?m(add|sub)", t))
    lanes = 4 if arch == "a64" else (16 if "avx512" in func_re else 8)
    triple = "aarch64" if arch == "a64" else "x86_64"
    ranked = sorted(((sum(1 for t in instructions(i, j) if is_fma(t)), i, j, lab) for i, j, lab in inner), reverse=True)
    for n, i, j, lab in ranked[:top]:
        ins = instructions(i, j)
        cells = []
        with tempfile.NamedTemporaryFile("w", suffix=".s") as f:
            f.write("\n".join(ins) + "\n")
            f.flush()
            for cpu in cpus:
                out = subprocess.run(["llvm-mca", f"-mtriple={triple}", f"-mcpu={cpu}", "-iterations=300", f.name],
                                     capture_output=True, text=True).stdout
                cycles = int(re.search(r"Total Cycles:\s+(\d+)", out).group(1)) / 300
                cells.append(f"{cpu} {cycles:.2f} cycles/iteration")
        print(f"{lab}: {len(ins)} instructions, {n} FMA x {lanes} lanes; " + ", ".join(cells))


if __name__ == "__main__":
    main()
