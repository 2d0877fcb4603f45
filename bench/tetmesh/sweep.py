"""Refusal and angle sweep of `isocube tetmesh` over every built-in sample, as a user runs it.

    python bench/tetmesh/sweep.py ISOCUBE_BINARY [--sizes 24,48,96] [--seeds 8] [--first-seed 1]
        [--samples sphere,noise,...] [--modes default,mc,...] [--jobs 2]

Every built-in sample (`isocube samples`' list but the contour stack) at each size, with seeds
1..S for the samples that take one (noise, packed-spheres), both sides (the values below the
level and, with `--flip`, the rest), and six option sets: the default (ternary, snap 0.3,
vertices on the crossings), `--method mc`, `--snap-position grid` (snap 0.3 on the grid
points), `--snap 0.5`, `--snap 0.5 --snap-position grid`, and the default with a graded
interior (`--max-size 64c`). Each run is the command end to end (sample, mesh, check, binary
`.msh` written). A run is *refused* when the command fails: the
message is kept and printed. For each option set the table gives meshed / refused and the
range of the smallest and largest dihedral angles over the meshes, how many meshes have an
angle outside [10°, 165°], and of those, by the summary's classes of the elements outside
(`outside [10°, 165°]: …`): meshes whose every such element has an edge where the region's
boundary is sharper than 10° (forced by the surface: the elements around that edge share its
angle), meshes whose such elements are all forced or within 1.5 cells of surface detail under the
snap distance (two surface vertices that close, or one that close to a wall: what snapping would
have removed, kept where it would change the topology — a gap or neck thinner than the elements;
for `--method mc`, which snaps nothing, the default's 0.3 cells), and the rest.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

SAMPLES = [
    "sphere",
    "torus",
    "two-tori",
    "tangle",
    "gyroid",
    "schwarz-p",
    "hyperboloid",
    "tubes",
]
SEEDED = ["noise", "packed-spheres"]
MODES = {
    "default": [],
    "mc": ["--method", "mc"],
    "0.3 grid": ["--snap-position", "grid"],
    "0.5": ["--snap", "0.5"],
    "0.5 grid": ["--snap", "0.5", "--snap-position", "grid"],
    "graded": ["--max-size", "64c"],
}
LOW, HIGH = 10.0, 165.0


@dataclass
class Run:
    mode: str
    spec: str
    flip: bool
    ok: bool
    low: float = float("nan")
    high: float = float("nan")
    sharpest: float | None = None
    # The summary's classes of the elements outside [10°, 165°]: at a boundary edge sharper
    # than 10°, beside surface detail under the snap distance, others.
    forced: int = 0
    fine: int = 0
    others: int = 0
    message: str = ""
    seconds: float = 0.0


def run(binary: str, work: Path, mode: str, spec: str, flip: bool) -> Run:
    out = work / f"{spec.replace(':', '-')}-{mode.replace(' ', '-')}-{int(flip)}.msh"
    args = [binary, "tetmesh", spec, "-o", str(out), "--binary", *MODES[mode]]
    if flip:
        args.append("--flip")
    start = time.perf_counter()
    done = subprocess.run(args, check=False, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    out.unlink(missing_ok=True)
    if done.returncode != 0:
        return Run(
            mode,
            spec,
            flip,
            False,
            message=done.stderr.strip().splitlines()[-1],
            seconds=seconds,
        )
    angles = re.search(r"dihedral angles ([0-9.]+)°\.\.([0-9.]+)°", done.stderr)
    if angles is None:
        raise SystemExit(f"{' '.join(args)}: no dihedral angles in\n{done.stderr}")
    sharpest = re.search(r"sharpest boundary edge: ([0-9.]+)°", done.stderr)
    classes = re.search(
        r"outside \[10°, 165°\]: [0-9]+ elements: ([0-9]+) at .*?, ([0-9]+) within .*?, ([0-9]+) others",
        done.stderr,
    )
    forced, fine, others = (int(g) for g in classes.groups()) if classes else (0, 0, 0)
    return Run(
        mode,
        spec,
        flip,
        True,
        float(angles.group(1)),
        float(angles.group(2)),
        float(sharpest.group(1)) if sharpest else None,
        forced,
        fine,
        others,
        seconds=seconds,
    )


def forced_by_surface(r: Run) -> bool:
    """Every element outside the range is at a boundary edge sharper than 10°."""
    return r.forced > 0 and r.fine == 0 and r.others == 0


def beside_fine_detail(r: Run) -> bool:
    """No element outside the range is other than forced or beside surface detail under the
    snap distance (and some is beside such detail)."""
    return r.fine > 0 and r.others == 0


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("binary")
    parser.add_argument("--sizes", default="24,48,96")
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument(
        "--first-seed", type=int, default=1, help="seeds first..first+seeds-1"
    )
    parser.add_argument(
        "--samples",
        default=",".join(SAMPLES + SEEDED),
        help="which samples (comma-separated)",
    )
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--modes", default=",".join(MODES))
    parser.add_argument(
        "--every", action="store_true", help="list every run, not only those outside"
    )
    options = parser.parse_args()
    sizes = [int(n) for n in options.sizes.split(",")]
    modes = options.modes.split(",")
    chosen = options.samples.split(",")
    unknown = [s for s in chosen if s not in SAMPLES + SEEDED]
    if unknown:
        parser.error(
            f"unknown sample(s) {', '.join(unknown)}; known: {', '.join(SAMPLES + SEEDED)}"
        )
    unknown = [m for m in modes if m not in MODES]
    if unknown:
        parser.error(f"unknown mode(s) {', '.join(unknown)}; known: {', '.join(MODES)}")
    seeds = range(options.first_seed, options.first_seed + options.seeds)
    specs = [f"sample:{s}:{n}" for s in SAMPLES if s in chosen for n in sizes]
    specs += [
        f"sample:{s}:{n}:{seed}"
        for s in SEEDED
        if s in chosen
        for n in sizes
        for seed in seeds
    ]
    jobs = [
        (mode, spec, flip) for mode in modes for spec in specs for flip in (False, True)
    ]
    with tempfile.TemporaryDirectory() as tmp, ThreadPoolExecutor(options.jobs) as pool:
        runs = list(pool.map(lambda job: run(options.binary, Path(tmp), *job), jobs))

    print(
        f"{len(specs)} inputs × 2 sides; sizes {options.sizes}, seeds {seeds.start}..{seeds.stop - 1}"
    )
    print()
    print(
        "| options | meshed | refused | smallest dihedral (min / median) | largest dihedral (max / median) "
        f"| outside [{LOW:g}°, {HIGH:g}°] | of those, forced by the surface | beside detail under the snap distance | others "
        "| elements outside: forced / beside detail / others | seconds |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for mode in modes:
        mine = [r for r in runs if r.mode == mode]
        good = [r for r in mine if r.ok]
        lows = sorted(r.low for r in good)
        highs = sorted(r.high for r in good)
        outside = [r for r in good if r.low < LOW or r.high > HIGH]
        forced = [r for r in outside if forced_by_surface(r)]
        fine = [r for r in outside if beside_fine_detail(r)]
        low = f"{lows[0]:.2f}° / {lows[len(lows) // 2]:.2f}°" if lows else "–"
        high = f"{highs[-1]:.2f}° / {highs[len(highs) // 2]:.2f}°" if highs else "–"
        elements = " / ".join(
            str(sum(getattr(r, c) for r in good)) for c in ("forced", "fine", "others")
        )
        seconds = sum(r.seconds for r in mine)
        print(
            f"| {mode} | {len(good)} | {len(mine) - len(good)} | {low} | {high} | {len(outside)} | {len(forced)} "
            f"| {len(fine)} | {len(outside) - len(forced) - len(fine)} | {elements} | {seconds:.0f} |"
        )
    print()
    for r in runs:
        if not r.ok:
            print(
                f"refused: {r.mode}: {r.spec}{' --flip' if r.flip else ''}: {r.message}"
            )
    for r in runs:
        if r.ok and (options.every or r.low < LOW or r.high > HIGH):
            side = " --flip" if r.flip else ""
            edge = (
                f", sharpest boundary edge {r.sharpest:.2f}°"
                if r.sharpest is not None
                else ""
            )
            edge += " (forced)" if forced_by_surface(r) else ""
            edge += (
                f"; elements outside: {r.forced} forced, {r.fine} beside fine detail, {r.others} others"
                if r.forced + r.fine + r.others
                else ""
            )
            kind = "outside" if r.low < LOW or r.high > HIGH else "inside"
            print(
                f"{kind}: {r.mode}: {r.spec}{side}: {r.low:.2f}°..{r.high:.2f}°{edge}, {r.seconds:.2f} s"
            )
    sys.stdout.flush()


if __name__ == "__main__":
    main()
