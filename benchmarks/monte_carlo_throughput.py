"""Monte Carlo throughput: samples per second against backend and chunk (batch) size, measured
through the public `tolerax.monte_carlo(...)` call, for the azimuth scan scene at lumped and at
planetary fidelity, the latter in full and at the fast setting.

    python benchmarks/monte_carlo_throughput.py [--scenes lumped planetary fast]
        [--backends vmap processes processes-free dask] [--chunks 1 4 16] [--worker-chunks 1 4] [--workers 2]
        [--output monte_carlo_throughput] [--results DIR]

Model: `tolerax.PointingObjective` on `tolerax.scan("azimuth", fidelity=(f, "ideal"))`, steady
start, 101 saves, the objective's solver defaults (Tsit5, rtol 1e-6, atol 1e-9), a short horizon
(`--lumped-duration`, `--planetary-duration`) with the pointing window its second half. `fast`:
the planetary stage at the fast setting (the built-in scene `scan-azimuth-fast`: `planetary-scaled`
with `mass_scaling` 1000, rtol 1e-3, atol 1e-6, PI controller 0.3/0.3), over `--fast-duration`. Samples:
the scene's clearances and backlash drawn uniformly within `tolerax.tolerances_of(scene,
band=--band)`, with one key for every configuration, so every configuration solves the same units.

Configurations (one timed `monte_carlo` call each, wall clock by `harness.wall`, progress bar off):

- `vmap`, chunk c in `--chunks`: first a warm-up call with one sample (padded to c, so it compiles
  the chunk's program), then the timed call.
- `processes`, `--workers` spawned processes, chunk c in `--worker-chunks`: every call starts its
  own pool, so each worker imports tolerax and compiles inside the timed call; its rate after
  start-up comes from the chunk-completion times the driver sees (`_rate_after_start`).
- `processes-free`: the same with `pin_workers=False`, each worker free to use every core (the
  engine's default pins each to a core of its own on a CPU, `processes` here).
- `dask`, a `distributed.LocalCluster(n_workers=--workers, threads_per_worker=1)` started once:
  per chunk size a warm-up call with c + 1 samples (two chunks, one per worker, each compiling),
  then the timed call.

A scene's sample count (`--lumped-samples`, `--planetary-samples`) should be a multiple of its
chunk sizes: a short chunk is padded and pays for the padding. vmap chunk sizes above the sample
count, and worker chunk sizes that give a worker fewer than two chunks (so no rate after start-up),
are skipped for that scene. Every configuration's outputs are compared with the vmap run of the same
chunk size (the engine promises identical results for the same key on every backend) and with
vmap at the smallest chunk. Writes `benchmarks/results/monte_carlo_throughput.md` (or
`--output`.md; `--results DIR`: in DIR), then exits with
status 1 if a backend disagreed with vmap at the same chunk size.
"""

import dataclasses
import os
import sys
import time

import jax
import numpy as np

import tolerax

import harness


OUTPUTS = ("pointing_rms", "pointing_peak", "pointing_smooth_peak", "tracking_speed_rms")


def _timed_call(model, tolerances, n, key, warmup=None, **kwargs):
    """One `monte_carlo` call (`harness.wall`): its result, wall time (s), and `(seconds from the
    call's start, samples in the chunk)` for each chunk in the order the driver received them.
    With `warmup` (a sample count), a warm-up call of that many samples with the same options
    comes first (it compiles the chunk's program); its wall time is returned first (None
    without one)."""
    warm = harness.wall(tolerax.monte_carlo, model, tolerances, warmup, key, progress=False, **kwargs)[0] if warmup else None
    done = []
    start = time.perf_counter()
    wall, res = harness.wall(
        tolerax.monte_carlo, model, tolerances, n, key, progress=False,
        callback=lambda k, ds: done.append((time.perf_counter() - start, ds.sizes["sample"])), **kwargs,
    )
    return warm, res, wall, done


def _rate_after_start(done, workers):
    """Samples per second once the first `workers` chunks have come back (each worker's start-up
    and compilation are in those): the samples of the later chunks over the time from the
    `workers`-th completion to the last. When the workers finish starting at different times,
    the later chunks include the last one's start-up, so this underestimates the rate. None when
    no chunk came back after them."""
    if len(done) <= workers:
        return None
    later = sum(size for _, size in done[workers:])
    return later / (done[-1][0] - done[workers - 1][0])


def _compare(res, ref) -> tuple[bool, float]:
    """Whether every output and the success flags are bitwise equal (NaN where both are NaN, as a
    failed solve may give), and the largest relative difference of the outputs finite in both."""
    a, b = res.dataset, ref.dataset
    identical = bool(np.array_equal(a["success"].values, b["success"].values))
    worst = 0.0
    for name in OUTPUTS:
        x, y = a[name].values, b[name].values
        identical &= bool(np.array_equal(x, y, equal_nan=True))
        finite = np.isfinite(x) & np.isfinite(y)
        if finite.any():
            worst = max(worst, float(np.max(np.abs(x - y)[finite] / np.maximum(np.abs(y[finite]), 1e-300))))
    return identical, worst


def measure(label, model, tolerances, n, key, args, client, chunks, worker_chunks):
    """Every configuration of one scene: a list of row dicts, and the disagreements found."""
    rows, refs, failures = [], {}, []
    loads = []  # the load average before each configuration's calls

    def timed_call(*a, **k):
        loads.append(harness.load())
        return _timed_call(*a, **k)

    def record(backend, chunk, warmup, res, wall, done, steady):
        row = dict(backend=backend, chunk=chunk, n=n, warmup=warmup, wall=wall, rate=n / wall, steady=steady,
                   ok=int(res.success.sum()), load=f"{loads[-1]} / {harness.load()}", per_chunk=np.diff([0.0] + [t for t, _ in done]),
                   workers="1 (in process)" if backend == "vmap" else str(args.workers))
        row["same"] = None if backend == "vmap" or chunk not in refs else _compare(res, refs[chunk])
        row["across"] = _compare(res, refs[min(refs)])[1] if refs else None
        if row["same"] is not None and not row["same"][0]:
            failures.append(f"{label} {backend} chunk {chunk}: differs from vmap at chunk {chunk} by {row['same'][1]:.2e}")
        rows.append(row)
        print(label, {k: v for k, v in row.items() if k != "per_chunk"}, flush=True)

    if "vmap" in args.backends:
        for chunk in chunks:
            warmup, res, wall, done = timed_call(model, tolerances, n, key, warmup=1, chunk_size=chunk)
            record("vmap", chunk, warmup, res, wall, done, n / wall)
            refs[chunk] = res
    for chunk in worker_chunks:  # pinned and free alternate, so a slow spell of the machine hits both
        for backend, pin in (("processes", None), ("processes-free", False)):
            if backend not in args.backends:
                continue
            _, res, wall, done = timed_call(model, tolerances, n, key, chunk_size=chunk, backend="processes",
                                             workers=args.workers, pin_workers=pin)
            record(backend, chunk, None, res, wall, done, _rate_after_start(done, args.workers))
    if "dask" in args.backends:
        for chunk in worker_chunks:
            warmup, res, wall, done = timed_call(model, tolerances, n, key, warmup=chunk + 1, chunk_size=chunk,
                                                  backend="dask", client=client)
            record("dask", chunk, warmup, res, wall, done, n / wall)
    return rows, failures, refs


def solver_error_note(model, tolerances, n, key, rows, refs) -> str:
    """The chunk-size differences beside the solver's own error: the same samples at vmap's
    smallest chunk solved with rtol and atol 1000 times tighter."""
    smallest = min(refs)
    tight = dataclasses.replace(model, rtol=model.rtol * 1e-3, atol=model.atol * 1e-3)
    reference = tolerax.monte_carlo(tight, tolerances, n, key, chunk_size=smallest, progress=False)
    error = _compare(refs[smallest], reference)[1]
    across = max((r["across"] for r in rows if r["across"] is not None), default=None)
    return (f"Chunk size against the solver's error: the largest relative difference between chunk sizes above "
            f"({_fmt(across, '.1e')}) against the solver's own error on these samples, vmap at chunk {smallest} against "
            f"the same solve with rtol and atol 1000 times tighter ({model.rtol * 1e-3:g}, {model.atol * 1e-3:g}): "
            f"{error:.1e}.")


def _fmt(x, spec):
    return "—" if x is None else format(x, spec)


COLUMNS = [
    "backend", "workers", "chunk", "samples", "warm-up call (s)", "timed call (s)", "samples/s, timed call",
    "samples/s after start-up", "succeeded", "outputs vs vmap, same chunk", "max rel. diff vs vmap, smallest chunk",
    "load 1/5/15 min before / after",
]


def table_rows(rows):
    out = []
    for r in rows:
        if r["backend"] == "vmap":
            same = "(reference)"
        elif r["same"] is None:
            same = "—"
        else:
            same = "identical" if r["same"][0] else f"differs by {r['same'][1]:.1e}"
        across = r["across"]
        across = "—" if across is None else ("identical" if across == 0.0 else f"{across:.1e}")
        out.append((
            r["backend"], r["workers"], str(r["chunk"]), str(r["n"]), _fmt(r["warmup"], ".1f"), f"{r['wall']:.1f}",
            f"{r['rate']:.3f}", _fmt(r["steady"], ".3f"), f"{r['ok']}/{r['n']}", same, across, r["load"],
        ))
    return out


def which_backend(rows, cluster_start) -> str:
    """A "which backend when" paragraph from this scene's rows alone: per backend its fastest chunk
    after start-up (against vmap at its smallest chunk), what a cold call costs before that rate
    is reached, and the predicted wall time of one cold call of 100, 1000 and 10000 samples."""
    best = {}
    for r in rows:
        if r["steady"] is not None and (r["backend"] not in best or r["steady"] > best[r["backend"]]["steady"]):
            best[r["backend"]] = r
    vmaps = [r for r in rows if r["backend"] == "vmap"]
    if not best or not vmaps:
        return ""
    one = vmaps[0]
    cold = {}
    parts = [f"Which backend when (from this table): after start-up, against vmap at chunk {one['chunk']} "
             f"({one['steady']:.3f} samples/s),"]
    for backend, r in best.items():
        # Cold cost, paid before the rate after start-up: vmap compiles in the driver (its warm-up
        # call, which also runs one padded chunk), once per process and chunk size; processes start
        # their pool and compile in each worker in every call (wall - samples / rate); dask starts
        # its cluster once and compiles in each worker once per chunk size (its warm-up call).
        if backend == "vmap":
            cold[backend] = r["warmup"]
        elif backend.startswith("processes"):
            cold[backend] = max(r["wall"] - r["n"] / r["steady"], 0.0)
        else:
            cold[backend] = r["warmup"] + (cluster_start or 0.0)
        parts.append(f"{backend} at chunk {r['chunk']} ran {r['steady']:.3f} samples/s (x{r['steady'] / one['steady']:.2f})"
                     f" after {cold[backend]:.0f} s of start-up{';' if backend != list(best)[-1] else '.'}")
    for n in (100, 1000, 10000):
        times = {b: cold[b] + n / best[b]["steady"] for b in best}
        pick = min(times, key=times.get)
        parts.append(f"{n} samples in one cold call: " + ", ".join(f"{b} {t / 60:.1f} min" for b, t in times.items())
                     + f" → {pick}.")
    return " ".join(parts)


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scenes", nargs="+", choices=("lumped", "planetary", "fast"), default=["lumped", "planetary", "fast"])
    parser.add_argument("--backends", nargs="+", choices=("vmap", "processes", "processes-free", "dask"),
                        default=["vmap", "processes", "dask"])
    parser.add_argument("--chunks", type=int, nargs="+", default=[1, 4, 16], help="vmap chunk sizes")
    parser.add_argument("--worker-chunks", type=int, nargs="+", default=[1, 4],
                        help="chunk sizes for processes and dask")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--lumped-duration", type=float, default=0.6, help="simulated time per sample (s)")
    parser.add_argument("--planetary-duration", type=float, default=0.2, help="simulated time per sample (s)")
    parser.add_argument("--fast-duration", type=float, default=0.6, help="simulated time per sample (s)")
    parser.add_argument("--lumped-samples", type=int, default=16)
    parser.add_argument("--planetary-samples", type=int, default=8)
    parser.add_argument("--fast-samples", type=int, default=16)
    parser.add_argument("--band", type=float, default=10e-6, help="tolerance half-width of every feature (m)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--output", default="monte_carlo_throughput", help="results file name (without .md)")
    args = harness.parse_args(parser)
    load_before = harness.load()
    key = jax.random.key(args.seed)
    client = cluster = cluster_start = None
    if "dask" in args.backends:
        import distributed

        def start_cluster():
            cluster = distributed.LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                                               dashboard_address=None)
            return cluster, distributed.Client(cluster)

        cluster_start, (cluster, client) = harness.wall(start_cluster)
    sections, failures = [], []
    try:
        for fidelity in args.scenes:
            start = time.perf_counter()
            duration = getattr(args, f"{fidelity}_duration")
            n = getattr(args, f"{fidelity}_samples")
            chunks = sorted(c for c in set(args.chunks) if c <= n)
            worker_chunks = sorted(c for c in set(args.worker_chunks) if -(-n // c) >= 2 * args.workers)
            if fidelity == "fast":
                scene = tolerax.scan("azimuth", fidelity=("planetary-scaled", "ideal"), mass_scaling=1000.0)
                solver = dict(rtol=1e-3, atol=1e-6, pcoeff=0.3, icoeff=0.3)
            else:
                scene, solver = tolerax.scan("azimuth", fidelity=(fidelity, "ideal")), {}
            model = tolerax.PointingObjective(scene, duration=duration, settle=duration / 2, start="steady",
                                              n_save=101, **solver)
            tolerances = tolerax.tolerances_of(scene, band=args.band)
            rows, bad, refs = measure(fidelity, model, tolerances, n, key, args, client, chunks, worker_chunks)
            failures += bad
            notes = [
                f"{n} samples per configuration; features {', '.join(tolerances.names)} at nominal ± "
                f"{args.band * 1e6:g} um, uniform; horizon {duration} s, pointing window from {duration / 2} s. "
                f"Section wall time {(time.perf_counter() - start) / 60:.1f} min."
            ]
            first = next((r for r in rows if r["backend"] == "vmap"), None)
            if first is not None:
                per = first["per_chunk"] / first["chunk"]
                notes.append(f"vmap at chunk {first['chunk']}, seconds per sample (from chunk-completion times): "
                             f"min {per.min():.2f}, median {np.median(per):.2f}, max {per.max():.2f}.")
            pairs = [(r, f) for r in rows if r["backend"] == "processes"
                     for f in rows if f["backend"] == "processes-free" and f["chunk"] == r["chunk"]]
            if pairs:
                notes.append("Workers pinned to a core each (`processes`, the default) against free (`processes-free`): "
                             + "; ".join(f"chunk {r['chunk']}: timed call {r['wall']:.1f} against {f['wall']:.1f} s "
                                         f"(x{r['wall'] / f['wall']:.2f}), rate after start-up "
                                         f"{_fmt(r['steady'], '.3f')} against {_fmt(f['steady'], '.3f')} samples/s"
                                         for r, f in pairs) + ".")
            if refs:
                notes.append(solver_error_note(model, tolerances, n, key, rows, refs))
            notes.append(which_backend(rows, cluster_start))
            heading = (f'{fidelity}: `scan("azimuth", fidelity=("{fidelity}", "ideal"))`' if fidelity != "fast" else
                       'fast: `scan("azimuth", fidelity=("planetary-scaled", "ideal"), mass_scaling=1000)`, rtol 1e-3, '
                       'atol 1e-6, PI 0.3/0.3') + f", {duration} s per sample"
            sections.append(harness.Section(heading, COLUMNS, table_rows(rows), notes))
    finally:
        if client is not None:
            client.close()
            cluster.close()
    intro = [
        f"Load average (1/5/15 min) before the run: {load_before}; after: {harness.load()}, on {os.cpu_count()} cores. "
        f"Dask cluster start-up ({args.workers} workers): {_fmt(cluster_start, '.1f')} s, in no row. "
        "Warm-up call: vmap, one sample padded to the chunk (compiles); dask, chunk + 1 samples (one chunk per "
        "worker, each compiles); processes have none, as every call starts its own pool, so their timed call "
        "includes start-up and compilation in each worker and their rate after start-up is read from the "
        "chunk-completion times (the samples of the chunks that came back after the first one per worker, over "
        "the time from then to the last).",
        "Reading it: wall-clock times. Each row gives the load average before and after its calls: the run's "
        "own driver, workers and Dask cluster raise it to about 2-3 on 2 cores, so a figure is a quiet-machine "
        "one where the load at the start was below 1.5 (nothing else running). Where other work shares the "
        "machine, several worker processes get more of its time slices than one process does, which favours "
        "processes and dask over vmap. The processes rate after start-up rests on the chunks that came back "
        "after each worker's first: with few chunks it is noisy (too low when the workers finish starting at "
        "different times). The predicted cold-call times in each section's closing note are start-up + "
        "samples / rate after start-up, with that section's figures.",
    ]
    if jax.devices()[0].platform == "cpu":
        intro.append(
            "No accelerator in this run, so there is no GPU column. On a GPU, run for example `--backends vmap "
            "--chunks 1 16 64 256 --lumped-samples 256 --planetary-samples 64`; for processes or dask workers on "
            "one GPU, set `XLA_PYTHON_CLIENT_PREALLOCATE=false`, or each worker claims most of its memory."
        )
    harness.write_table(
        args.output,
        "Monte Carlo throughput by backend and chunk size (azimuth scan scene, `tolerax.monte_carlo`)",
        harness.command(args),
        sections[0].columns, sections[0].rows,
        intro=intro + [f"## {sections[0].heading}"],
        notes=list(sections[0].notes),
        sections=sections[1:],
    )
    if failures:
        print("Backends disagree:\n" + "\n".join(failures), file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
