"""Models the hottest loops of a profile on CPUs we have no host of (issue 47: the Intel
Xeon's AVX2 path), with LLVM's machine-code analyser.

    perf record -e cpu-clock -o cues.data BIN bench ten.wav -r ratemap,ild,itd,ic \\
        --threads 0 --chunk 441 --repeat 5
    python tools/model_kernels.py BIN cues.data [--top 6] [--cpus icelake-server,...]

For each of the `top` symbols with the most samples (each instance of a generic kernel
apart), it takes the innermost loop holding at least 40 % of the symbol's samples (a
backward jump in the disassembly and its body), and prints the loop's share of all
samples, its instructions, its floating-point arithmetic, and the cycles per iteration
`llvm-mca` predicts on each CPU model (throughput-bound, data in the first-level cache). BIN needs
symbols (a release build keeps them). Needs perf, objdump and llvm-mca (Debian's binutils,
linux-perf and llvm). A model, not a measurement: compare it with the measured
profile of a host whose model it has.
"""

import argparse
import bisect
import collections
import re
import subprocess

ARITHMETIC = re.compile(r"^v?(f?n?m(ul|add|sub)\w*|add|sub|mul|div)[sp][sd]\b")


def run(*cmd):
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"{cmd[0]} failed: {done.stderr.strip()}")
    return done.stdout


def symbols(binary):
    """(start, size, name) of each function symbol, by `nm`."""
    out = []
    for line in run("nm", "-C", "-S", binary).splitlines():
        parts = line.split(None, 3)
        if len(parts) == 4 and parts[2] in "tTwW":
            out.append((int(parts[0], 16), int(parts[1], 16), parts[3]))
    return out


def samples(data, syms):
    """Sample counts by static address: perf reports run-time addresses of the
    position-independent binary, so the load offset is read off a symbol of one instance."""
    starts = collections.defaultdict(list)
    for start, _, name in syms:
        starts[name].append(start)
    counts, base = collections.Counter(), None
    for line in run("perf", "script", "-G", "-i", data, "-F", "ip,sym,symoff").splitlines():
        m = re.match(r"\s*([0-9a-f]+)\s+(.*)\+0x([0-9a-f]+)$", line.strip())
        if not m:
            continue
        ip = int(m.group(1), 16)
        if base is None and len(starts.get(m.group(2), [])) == 1:
            base = ip - int(m.group(3), 16) - starts[m.group(2)][0]
        counts[ip] += 1
    if base is None:
        raise SystemExit("no sample falls in a symbol of BIN: is it the profiled binary?")
    return collections.Counter({ip - base: n for ip, n in counts.items()})


def disassemble(binary, start, size):
    text = run("objdump", "-d", "--no-show-raw-insn", "-M", "att",
               f"--start-address={start}", f"--stop-address={start + size}", binary)
    out = []
    for line in text.splitlines():
        m = re.match(r"\s+([0-9a-f]+):\s+(.*)", line)
        if m:
            out.append((int(m.group(1), 16), m.group(2).split("#")[0].strip()))
    return out


def hot_loop(code, counts):
    """The innermost loop with at least 40 % of the function's samples (a kernel over
    the two segments of a frame has two such loops, each with about half)."""
    loops = []
    for address, text in code:
        m = re.match(r"j\w+\s+([0-9a-f]+)", text)
        if m and code[0][0] <= int(m.group(1), 16) <= address:
            body = [(a, t) for a, t in code if int(m.group(1), 16) <= a <= address]
            loops.append((sum(counts[a] for a, _ in body), body))
    if not loops:
        return 0, []
    total = sum(counts[a] for a, _ in code)
    hot = [x for x in loops if x[0] >= 0.4 * total]
    if not hot:
        return max(loops, key=lambda x: x[0])
    return min(hot, key=lambda x: len(x[1]))


def cycles(body, cpu, path="/tmp/afe-model-loop.s"):
    with open(path, "w") as f:
        for _, text in body:
            if not text.startswith("j"):
                f.write(re.sub(r"<[^>]*>", "", text) + "\n")
    out = run("llvm-mca", f"-mcpu={cpu}", "-iterations=300", path)
    return int(re.search(r"Total Cycles:\s+(\d+)", out).group(1)) / 300


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("binary")
    parser.add_argument("data")
    parser.add_argument("--top", type=int, default=6)
    parser.add_argument("--cpus", default="icelake-server")
    args = parser.parse_args()
    syms = symbols(args.binary)
    counts = samples(args.data, syms)
    total = sum(counts.values())
    syms.sort()
    starts = [start for start, _, _ in syms]
    weight = collections.Counter()
    for address, n in counts.items():
        i = bisect.bisect_right(starts, address) - 1
        if i >= 0 and address < syms[i][0] + syms[i][1]:
            weight[i] += n
    cpus = args.cpus.split(",")
    print(f"{'share':>6} {'loop':>5} {'arith':>5}  " + " ".join(f"{c:>16}" for c in cpus)
          + "  symbol (cycles per loop iteration)")
    for i, _ in weight.most_common(args.top):
        sym = syms[i]
        n, body = hot_loop(disassemble(args.binary, sym[0], sym[1]), counts)
        if not body:
            continue
        arith = sum(bool(ARITHMETIC.match(t)) for _, t in body)
        modelled = " ".join(f"{cycles(body, c):16.1f}" for c in cpus)
        print(f"{100 * n / total:5.1f}% {len(body):5} {arith:5}  {modelled}  {sym[2][:70]}")


if __name__ == "__main__":
    main()
