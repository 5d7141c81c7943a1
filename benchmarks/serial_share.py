"""What one thread runs while the other threads of the pool wait: the step's unshared work, from
a `perf record` of a step benchmark.

    perf record -F 600 --call-graph dwarf,16384 -o FILE.data -- \
        .venv/bin/python benchmarks/stage_profile.py --ny 256 --active-region 16 \
        --sides open-right-top --threads 2 --at-time 1.5 --cache DIR --steps 40
    .venv/bin/python benchmarks/serial_share.py FILE.data [--top 25] [--out FILE.json]

During a step the pool's threads that have no work wait actively for it
(`exec::with_active_workers`: rayon's `yield_now` and a pause), so a sample of a thread in that
loop marks a moment when it had nothing to do. For each such sample the script takes the
sample of the busiest other thread nearest in time (within 2 ms) and, when that thread was
working, charges its function (the first granrs frame of its call chain) and the room it ran
in. The shares are of the wall time of the profiled process's two busiest threads, so "6.9 %"
means that for 6.9 % of the time one thread ran that function while the other waited: work
that a second thread did not share, either because it runs on one thread (a Gauss–Seidel
sweep, a coarse level, a triangular solve) or because a parallel sweep gave the threads
unequal shares. Frames are resolved by `perf script` (Debian package linux-perf); without
`--call-graph dwarf` only the leaf function is known and the rooms are not.
"""

from __future__ import annotations

import argparse
import bisect
import collections
import json
import re
import subprocess
import sys

#: Leaf functions of a thread that waits for work (the active wait, rayon's idle loop, the
#: kernel's scheduler).
WAITING = (
    "rayon_core::scope::ScopeBase::execute_job_closure",
    "rayon_core::registry",
    "rayon_core::sleep",
    "rayon_core::latch",
    "crossbeam",
    "std::thread::yield_now",
    "_raw_spin",
    "finish_task_switch",
    "__schedule",
    "schedule",
    "syscall",
    "__sched_yield",
    "do_sched_yield",
    "entry_SYSCALL",
    "__x64_sys",
    "futex",
    "do_syscall",
    "exit_to_user",
    "syscall_exit",
    "clear_bhb",
)

#: Rooms of the step, by a name that appears in the call chain (first match wins).
ROOMS = (
    ("pressure projection", ("PressureProjection", "FreeSurfaceProjection")),
    ("pore pressure", ("PorePressure",)),
    ("interface: redistancing", ("redistance", "Redistancer")),
    ("interface: transport", ("levelset::transport", "LevelSetTransport")),
    ("interface: mass correction", ("correct_mass",)),
    ("predictor (viscous solve)", ("MomentumSolver", "time_stepping::momentum")),
    ("rheology (Picard projections)", ("rheology",)),
    ("diagnostics", ("diagnostics", "energy")),
    ("properties", ("properties",)),
    ("snapshot, window", ("checkpoint", "window")),
)


def read_samples(data: str) -> list[tuple[int, float, list[str]]]:
    """(thread id, time, call chain leaf first) of every sample of `perf script`."""
    out = subprocess.run(
        ["perf", "script", "-i", data, "-F", "tid,time,ip,sym"], capture_output=True, text=True, check=True
    ).stdout
    samples, cur = [], None
    for line in out.splitlines():
        if not line.strip():
            if cur:
                samples.append(cur)
            cur = None
            continue
        if not line.startswith("\t"):  # a sample's header; its frames follow, indented by a tab
            head = line.split()
            cur = (int(head[0]), float(head[1].rstrip(":")), [])
        elif cur is not None:
            parts = line.strip().split(None, 1)
            cur[2].append(parts[1] if len(parts) > 1 else parts[0])
    if cur:
        samples.append(cur)
    return samples


def waiting(chain: list[str]) -> bool:
    return bool(chain) and chain[0].startswith(WAITING)


def function(chain: list[str]) -> str:
    """The first granrs frame that is not a generic helper (closures and SIMD copies folded)."""
    for f in chain:
        if "granrs_core" not in f:
            continue
        g = re.sub(r"::\{\{closure\}\}|::avx2|::avx512|::fallback", "", f)
        if not any(x in g for x in ("exec::", "par::", "impls::", "iter::")):
            return g[:110]
    return chain[0][:110] if chain else "?"


def room(chain: list[str]) -> str:
    text = " ".join(chain)
    for name, keys in ROOMS:
        if any(k in text for k in keys):
            return name
    return "other (no room in the chain)"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data", help="perf.data of a step benchmark")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    samples = read_samples(args.data)
    tids = [t for t, _ in collections.Counter(s[0] for s in samples).most_common(2)]
    if len(tids) < 2:
        print("fewer than two threads in the profile", file=sys.stderr)
        return 1
    by = {t: sorted((s for s in samples if s[0] == t), key=lambda s: s[1]) for t in tids}
    times = {t: [s[1] for s in by[t]] for t in tids}
    wall = (len(by[tids[0]]) + len(by[tids[1]])) / 2
    funcs, rooms = collections.Counter(), collections.Counter()
    waits = both = 0
    for a, b in ((tids[0], tids[1]), (tids[1], tids[0])):
        for s in by[a]:
            if not waiting(s[2]):
                continue
            waits += 1
            k = bisect.bisect_left(times[b], s[1])
            near = [by[b][i] for i in (k - 1, k) if 0 <= i < len(by[b])]
            o = min(near, key=lambda x: abs(x[1] - s[1]))
            if abs(o[1] - s[1]) > 0.002:
                continue
            if waiting(o[2]):
                both += 1
                continue
            funcs[function(o[2])] += 1
            rooms[room(o[2])] += 1
    unshared = sum(rooms.values())
    print(
        f"samples per thread: {wall:.0f}; one thread waiting while the other works: {unshared / wall:.1%} of the wall time; both waiting: {both / wall:.1%}"
    )
    print("\n| room | share of the wall time |\n|---|---|")
    for name, n in rooms.most_common():
        print(f"| {name} | {n / wall:.1%} |")
    print("\n| function (the working thread) | share of the wall time |\n|---|---|")
    for name, n in funcs.most_common(args.top):
        print(f"| `{name}` | {n / wall:.1%} |")
    if args.out:
        with open(args.out, "w") as f:
            json.dump(
                {
                    "data": args.data,
                    "samples_per_thread": wall,
                    "unshared_share": unshared / wall,
                    "both_waiting_share": both / wall,
                    "rooms": {k: v / wall for k, v in rooms.most_common()},
                    "functions": {k: v / wall for k, v in funcs.most_common()},
                },
                f,
                indent=1,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
