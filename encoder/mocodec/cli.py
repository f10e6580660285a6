"""The ``mocodec`` command line: encode, decode, info, eval, view, demo.

Every error a user can cause (a bad BVH, a tolerance that cannot be met, a corrupted asset)
is printed as one line starting with ``mocodec: error:`` and exits with status 1; usage
errors exit with 2; Ctrl-C exits with 130 and SIGTERM with 143. Every file is written
atomically (:mod:`mocodec.output`), never over one of the command's inputs, and names and paths
from files are printed with escapes for anything a terminal would act on. Set
``MOCODEC_DEBUG=1`` to see tracebacks.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from . import __version__, codecs
from .limits import clip_name_problem, printable
from .output import check_output, write_atomic
from .codecs import DEFAULT_CODEC
from .tolerance import DEFAULT_TOLERANCE_CM

if TYPE_CHECKING:
    from mocodec_runtime import ClipInfo

    from .runtime import Asset

EPILOG = """\
examples:
  mocodec encode walk.bvh run.bvh -o moves.mcd --tolerance 0.5
  mocodec encode ../mocap/ -o library.mcd --tolerance 1 --units cmu
  mocodec encode hero.glb -o hero.mcd --rate 30
  mocodec decode moves.mcd -o walk_decoded.bvh --clip walk
  mocodec decode hero.mcd -o hero_decoded.glb
  mocodec info moves.mcd
  mocodec eval walk.bvh --tolerance 0.1 --json
  mocodec eval walk.bvh --sweep 0.1 0.5 1 2 --codecs rma spline --plot curve.html
  mocodec view moves.mcd --original walk.bvh run.bvh -o moves.html

The tolerance is a promise: the largest world-space position error of any joint or end site
(and of a point beyond every glTF leaf joint) on any frame, in centimetres, measured through
the C runtime an engine uses. glTF is in metres. BVH files have no units: give --units or
--cm-per-unit, or mocodec guesses from the figure's animated poses (one unit for clips that
share a skeleton), says what it assumed, and warns about a figure under 50 or over 300 cm.
"""


def _codec_list() -> str:
    """The codecs, one line each, from the registry."""
    width = max(len(n) for n in codecs.available())
    return "\n".join(f"  {c.name:<{width}}  {c.summary}" for c in codecs.CODECS)


class CliError(Exception):
    """A failure to report as one line."""


class Terminated(BaseException):
    """SIGTERM: unwinds like Ctrl-C, so no temporary file is left behind."""


# ----------------------------------------------------------------------------- helpers
def _progress(total: int, enabled: bool):
    """A progress callback for multi-clip work (:class:`mocodec.bake.progress.Progress`)."""
    from .bake.progress import Progress

    return Progress(total, enabled)


def _expand_inputs(inputs: Sequence[str]) -> list[Path]:
    from .load import InputError, expand

    try:
        paths = expand(inputs)
    except InputError as exc:
        raise CliError(printable(str(exc))) from None
    # A file named twice (again by a folder, a link or another spelling) is one clip, not two.
    seen: set[str] = set()
    unique = []
    for p in paths:
        real = os.path.realpath(p)
        if real in seen:
            _warn(f"{p}: given more than once; read once")
            continue
        seen.add(real)
        unique.append(p)
    return unique


def _warn(message: str) -> None:
    print(f"mocodec: warning: {printable(message)}", file=sys.stderr)


def _load(paths: list[Path], args: argparse.Namespace, quiet: bool):
    """The clips as a streamed library (:mod:`mocodec.bake.library`: each file read once here,
    kept in memory while the library is small) and their units."""
    from .bake.library import open_library
    from .units import figure_facts, resolve_library_units

    facts = []
    motions = open_library(paths, getattr(args, "rate", None), visit=lambda i, m: facts.append(figure_facts(m)))
    units = resolve_library_units(motions, args.units, args.cm_per_unit,
                                  strict=bool(getattr(args, "strict", False)), warn=_warn, facts=facts)
    if not quiet:
        described = {}
        for ref, u in zip(motions.refs, units):
            described.setdefault(u.describe(), []).append(ref.name)
        for text, clips in described.items():
            which = printable(clips[0]) if len(clips) == 1 else f"{len(clips)} clips"
            print(f"{which}: {text}", file=sys.stderr)
    return motions, units


def _parse_option(text: str) -> tuple[str, Any]:
    if "=" not in text:
        raise CliError(f"-O expects KEY=VALUE, got {text!r}")
    key, value = text.split("=", 1)
    parsed: Any = value
    try:
        parsed = json.loads(value)
    except json.JSONDecodeError:
        pass
    if isinstance(parsed, list):
        parsed = tuple(parsed)
    return key.replace("-", "_"), parsed


def _codec_options(args: argparse.Namespace) -> dict[str, Any]:
    options = dict(_parse_option(o) for o in (args.option or []))
    if getattr(args, "pca_variance", None) is not None:
        options["variance"] = args.pca_variance
    return options


def _codec_choice(args: argparse.Namespace) -> str:
    """``--pca-variance`` asks for seed 003's subspace representation: codec rma-pca."""
    variance = getattr(args, "pca_variance", None)
    if variance is None:
        return args.codec
    if args.codec not in ("rma", "rma-pca"):
        raise CliError(f"--pca-variance is a setting of codec rma (seed 003's PCA), not of {args.codec!r}")
    if not 0.0 < variance <= 1.0:
        raise CliError(f"--pca-variance must be in (0, 1], got {variance}")
    if getattr(args, "contacts", False):
        raise CliError("--contacts needs a tolerance promise; --pca-variance makes none")
    return "rma-pca"


def _encode(args: argparse.Namespace, paths: list[Path] | None = None):
    from .encode import encode_motions
    from .tolerance import Tolerance

    quiet = getattr(args, "quiet", False)
    paths = paths or _expand_inputs(args.inputs)
    tolerance = Tolerance(args.tolerance, args.effector_tolerance)  # before the inputs are read
    if args.effector_tolerance is not None and args.effector_tolerance >= args.tolerance:
        _warn(f"--effector-tolerance {args.effector_tolerance:g} cm is not tighter than --tolerance "
              f"{args.tolerance:g} cm: every node is held to {args.tolerance:g} cm")
    motions, units = _load(paths, args, quiet or getattr(args, "json", False))
    codec = _codec_choice(args)
    if not quiet and not getattr(args, "json", False):
        eff = f", end effectors {args.effector_tolerance} cm" if args.effector_tolerance else ""
        variance = _codec_options(args).get("variance")
        promise = (f"PCA keeping {'its default share' if variance is None else f'{variance:g}'} of the "
                   "variance (no error bound: the error reached is reported)") if codec == "rma-pca" \
            else f"tolerance {args.tolerance} cm{eff}"
        print(f"encoding {len(motions)} clip(s) with codec {codec!r}, {promise}", file=sys.stderr)
    progress = _progress(len(motions), not quiet and not getattr(args, "json", False))
    try:
        with _runner(args) as runner:
            result = encode_motions(motions, units, codec, tolerance, _codec_options(args), progress,
                                    contacts=bool(getattr(args, "contacts", False)), runner=runner)
    finally:
        progress.close()
    return motions, result, runner.workers


def _runner(args: argparse.Namespace):
    """Where the clips are encoded: ``--jobs``, ``--scheduler``, ``--cache`` (mocodec.bake)."""
    from .bake import make_runner

    try:
        return make_runner(getattr(args, "jobs", None), getattr(args, "scheduler", None),
                           getattr(args, "cache", None))
    except (ValueError, OSError) as exc:
        raise CliError(str(exc)) from None


def _fmt_int(n: float) -> str:
    return f"{int(round(n)):,}"


def _summary_lines(result) -> list[str]:
    from .metrics import combine

    size = result.size
    err = combine([c.error for c in result.clips])
    frames = sum(c.frames for c in result.clips)
    return [
        f"clips: {len(result.clips)} ({_fmt_int(frames)} frames, {size.seconds:.1f} s)   "
        f"codec: {result.codec}   " + (f"tolerance: {result.tolerance.tolerance_cm} cm" if result.promise else
                                       f"PCA variance {result.settings.get('pca_variance')} (no tolerance)"),
        f"size: {_fmt_int(size.asset_bytes)} bytes ({_fmt_int(size.bytes_per_second)} B/s of animation)",
        f"ratio: {size.ratio_bvh:.1f}:1 vs the source's float32 channels ({_fmt_int(size.raw_bvh_bytes)} B)   "
        f"{size.ratio_acl:.1f}:1 vs ACL's 40 B per bone-sample ({_fmt_int(size.raw_acl_bytes)} B)",
        f"error through the C runtime (cm): max {err['max_cm']:.4f}  p99 {err['p99_cm']:.4f}  "
        f"mean {err['mean_cm']:.4f}   " + (f"(max {err['max_pct_height']:.3f} % of height)"
                                          if err["max_pct_height"] is not None else "(the skeleton has no height)"),
        f"encode time: {result.encode_seconds:.1f} s",
        *result.notes,
    ]


def _clip_table(result) -> list[str]:
    rows = [f"  {'clip':<14} {'frames':>7} {'bytes':>9} {'max cm':>8} {'p99 cm':>8} {'mean cm':>8}"]
    for c in result.clips:
        rows.append(f"  {printable(c.name):<14} {c.frames:>7} {c.stats.get('payload_bytes', 0):>9,} "
                    f"{c.error.max_cm:>8.4f} {c.error.p99_cm:>8.4f} {c.error.mean_cm:>8.4f}")
    return rows


def _joint_table(motions, result) -> list[str]:
    names = motions[0].skeleton.names
    same = all(m.skeleton.names == names for m in motions)
    if not same:
        return ["  (clips have different skeletons: per-joint table omitted)"]
    mx = np.max([c.error.per_node_max_cm for c in result.clips], axis=0)
    frames = np.array([c.frames for c in result.clips], dtype=np.float64)
    mean = np.average([c.error.per_node_mean_cm for c in result.clips], axis=0, weights=frames)
    rows = [f"  {'joint':<20} {'max cm':>8} {'mean cm':>8}"]
    for i, n in enumerate(names):
        rows.append(f"  {printable(n):<20} {mx[i]:>8.4f} {mean[i]:>8.4f}")
    return rows


def _result_json(result) -> dict[str, Any]:
    from .metrics import combine

    return {
        "codec": result.codec,
        "tolerance_cm": result.tolerance.tolerance_cm if result.promise else None,
        "effector_tolerance_cm": result.tolerance.effector_tolerance_cm if result.promise else None,
        **({} if result.promise else {"pca_variance": result.settings.get("pca_variance")}),
        "size": result.size.as_dict(),
        "error": combine([c.error for c in result.clips]),
        "encode_seconds": result.encode_seconds,
        "notes": result.notes,
        "clips": [
            {"name": c.name, "frames": c.frames, "units": c.units.label,
             "cm_per_unit": c.units.cm_per_unit, **c.error.as_dict(), **c.stats}
            for c in result.clips
        ],
    }


def _peak_rss_kib() -> int:
    """This process's peak resident set since it started its program (Linux ``VmHWM``; the
    ``getrusage`` figure would include the process it was forked from)."""
    import resource

    try:
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))
    except (OSError, StopIteration, ValueError):
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss


def _bake_summary(result, workers: int, seconds: float) -> dict[str, Any]:
    """The bake in a few numbers (``--json``'s ``bake``): clips, asset bytes, wall seconds from
    reading the first file to the asset written, raw MB/s in ACL's convention (40 B per
    bone-sample) and of the BVH float32 channels, cache hits, the error per codec, and the peak
    resident memory of this process and of its largest worker process (``getrusage``: at most
    that, as Linux counts what the worker was forked from too)."""
    import resource

    from .metrics import combine

    mb = 1e6 * max(seconds, 1e-9)
    kib = 1024 / 1e6  # KiB to MB
    return {
        "clips": len(result.clips),
        "bytes": result.size.asset_bytes,
        "seconds": round(seconds, 3),
        "workers": workers,
        "mb_per_s": round(result.size.raw_acl_bytes / mb, 3),
        "bvh_mb_per_s": round(result.size.raw_bvh_bytes / mb, 3),
        "cache_hits": sum(bool(c.stats.get("cached")) for c in result.clips),
        "error": {result.codec: combine([c.error for c in result.clips])},
        "peak_rss_mb": {"main": round(_peak_rss_kib() * kib, 1),
                        "largest_worker": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * kib, 1)},
    }


# ----------------------------------------------------------------------------- commands
def cmd_encode(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    paths = _expand_inputs(args.inputs)
    out = check_output(args.output, paths)
    _, result, workers = _encode(args, paths)
    write_atomic(out, result.asset)
    if args.json:
        data = _result_json(result)
        data["bake"] = _bake_summary(result, workers, time.perf_counter() - started)
        print(json.dumps(data, indent=2))
    elif not args.quiet:
        print(f"wrote {printable(str(out))}")
        print("\n".join(_summary_lines(result)))
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """Size against error of one or more codecs over the tolerances of --sweep."""
    from .sweep import points_json, run_sweep, sweep_html, sweep_png

    if args.output:
        raise CliError("--sweep writes many assets' figures, not one asset: drop -o (use --plot FILE)")
    names = args.codecs or [args.codec]
    unknown = [n for n in names if n not in codecs.available()]
    if unknown:
        raise CliError(f"unknown codec {unknown[0]!r} (codecs: {', '.join(codecs.available())})")
    if any(not t > 0 for t in args.sweep):
        raise CliError("--sweep tolerances must be positive centimetres")
    plot = Path(args.plot or "sweep.html")
    if plot.suffix.lower() not in (".html", ".png"):
        raise CliError(f"{printable(str(plot))}: --plot writes .html or .png")
    paths = _expand_inputs(args.inputs)
    plot = check_output(plot, paths)
    motions, units = _load(paths, args, args.quiet or args.json)
    progress = _progress(len(names) * len(args.sweep), not args.quiet and not args.json)
    with _runner(args) as runner:
        points = run_sweep(motions, units, names, args.sweep, _codec_options(args), progress, runner)
    frames = sum(m.frame_count for m in motions)
    description = (f"{len(motions)} clip(s), {frames:,} frames ({', '.join(m.name for m in motions[:6])}"
                   f"{', ...' if len(motions) > 6 else ''}); codecs {', '.join(names)}; tolerances "
                   f"{', '.join(f'{t:g}' for t in sorted(args.sweep))} cm; measured through the C runtime.")
    if plot.suffix.lower() == ".png":
        sweep_png(points, description, plot)
    else:
        write_atomic(plot, sweep_html(points, description))
    if args.json:
        print(json.dumps({"plot": str(plot), "points": points_json(points)}, indent=2))
        return 0
    print(f"  {'codec':<12} {'tol cm':>7} {'bytes':>10} {'ratio':>7} {'max cm':>8} {'p99 cm':>8} {'mean cm':>8}")
    for p in points:
        if p.failed:
            print(f"  {p.codec:<12} {p.tolerance_cm:>7g}  not met: {p.failed}")
        else:
            print(f"  {p.codec:<12} {p.tolerance_cm:>7g} {p.asset_bytes:>10,} {p.ratio_bvh:>7.1f} "
                  f"{p.max_cm:>8.4f} {p.p99_cm:>8.4f} {p.mean_cm:>8.4f}")
    print(f"wrote {printable(str(plot))}")
    return 0


def cmd_eval(args: argparse.Namespace) -> int:
    if args.sweep:
        return cmd_sweep(args)
    if args.codecs or args.plot:
        raise CliError("--codecs and --plot go with --sweep")
    started = time.perf_counter()
    paths = _expand_inputs(args.inputs)
    out = check_output(args.output, paths) if args.output else None
    motions, result, workers = _encode(args, paths)
    if out is not None:
        write_atomic(out, result.asset)
    if args.json:
        data = _result_json(result)
        data["bake"] = _bake_summary(result, workers, time.perf_counter() - started)
        if all(m.skeleton.names == motions[0].skeleton.names for m in motions):
            data["per_joint"] = {
                n: {"max_cm": float(mx)} for n, mx in
                zip(motions[0].skeleton.names,
                    np.max([c.error.per_node_max_cm for c in result.clips], axis=0))
            }
        print(json.dumps(data, indent=2))
        return 0
    print("\n".join(_summary_lines(result)))
    print("\nper clip:")
    print("\n".join(_clip_table(result)))
    print("\nper joint (max over clips):")
    print("\n".join(_joint_table(motions, result)))
    return 0


def cmd_decode(args: argparse.Namespace) -> int:
    from .decode import decode_clip, write_asset_gltf
    from .io import write_bvh

    data, asset = _open_asset(args.asset)
    clips = [_clip_by_name(asset, args.asset, args.clip)] if args.clip else asset.clips
    out = Path(args.output)
    if out.suffix.lower() in (".glb", ".gltf"):
        write_asset_gltf(data, check_output(out, [args.asset]), [c.index for c in clips])
        if not args.quiet:
            print(f"wrote {printable(str(out))} ({len(clips)} clip(s) as glTF animations, decoded by the C runtime)")
        return 0
    # -o DIR/ (or an existing folder, or several clips): one file per clip, named after it.
    folder = out.is_dir() or args.output.endswith(("/", os.sep)) or len(clips) > 1
    # The runtime refuses clip names that steer a path; checked again where they become one.
    for c in clips:
        if folder and clip_name_problem(c.name):
            raise CliError(f"{printable(args.asset)}: {clip_name_problem(c.name)}: not written as a file name")
    if len(clips) > 1 and out.suffix.lower() == ".bvh" and not out.is_dir():
        raise CliError(f"the asset holds {len(clips)} clips: give --clip NAME, or a folder for -o")
    if folder and out.exists() and not out.is_dir():
        raise CliError(f"{printable(str(out))}: not a folder (the asset holds {len(clips)} clips)")
    targets = [check_output(out / f"{c.name}.bvh" if folder else out, [args.asset], folder_made=folder)
               for c in clips]
    if folder:
        out.mkdir(parents=True, exist_ok=True)
    progress = _progress(len(clips), not args.quiet)
    for c, target in zip(clips, targets):
        motion = decode_clip(asset, c.index)
        sk = motion.skeleton
        if sk.is_virtual.any() or np.any(sk.rest_rotations != [0.0, 0.0, 0.0, 1.0]) or np.any(sk.rest_scales != 1):
            raise CliError(f"clip {c.name!r} comes from glTF (rest rotations and scales, no BVH "
                           "channels): decode it to a .glb or .gltf file")
        write_bvh(motion, target, precision=args.precision)
        progress(c.name)
        if not args.quiet:
            print(f"wrote {printable(str(target))} ({c.frame_count} frames, decoded by the C runtime)")
    return 0


def _read_asset(path: str) -> bytes:
    p = Path(path)
    if not p.exists():
        raise CliError(f"{printable(str(p))}: no such file")
    if not p.is_file():
        raise CliError(f"{printable(str(p))}: not a regular file")
    return p.read_bytes()


def _open_asset(path: str) -> tuple[bytes, "Asset"]:
    """The asset's bytes, opened by the runtime; bytes it refuses end in one line naming the file
    and the runtime's reason (not the call that gave it)."""
    from .runtime import Asset, RuntimeResultError

    data = _read_asset(path)
    try:
        return data, Asset(data)
    except RuntimeResultError as exc:
        raise CliError(f"{printable(path)}: {RuntimeResultError(int(exc.code))}") from None


def _clip_by_name(asset: "Asset", path: str, name: str) -> "ClipInfo":
    """The clip called `name`; a name the asset does not hold is refused with the ones it does."""
    found = [c for c in asset.clips if c.name == name]
    if not found:
        names = [printable(c.name) for c in asset.clips]
        listed = ", ".join(names[:10]) + (f" and {len(names) - 10} more" if len(names) > 10 else "")
        raise CliError(f"{printable(path)}: no clip named {printable(name)!r} (it holds {listed})")
    return found[0]


def cmd_info(args: argparse.Namespace) -> int:
    from .container import read_summary

    data, asset = _open_asset(args.asset)
    summary = read_summary(data)
    clips = []
    for c in asset.clips:
        meta = summary.meta.get("clips", {}).get(c.name, {})
        raw = meta.get("raw_bvh_bytes")
        clips.append({
            "name": c.name, "codec": _codec_name(c.codec), "frames": c.frame_count,
            "frame_rate": round(float(c.frame_rate), 4), "duration_s": round(float(c.duration), 4),
            "skeleton": c.skeleton, "nodes": c.node_count,
            "max_error_cm": meta.get("max_error_cm"), "mean_error_cm": meta.get("mean_error_cm"),
            "raw_bvh_bytes": raw,
        })
    raw_total = sum(c["raw_bvh_bytes"] or 0 for c in clips)
    info = {
        "file": str(args.asset), "bytes": len(data), "format": f"{summary.version[0]}.{summary.version[1]}",
        "valid": "OK", "scratch_bytes": asset.scratch_size,
        "engine_bytes": len(data) + asset.scratch_size,
        "sections": [{"kind": k, "version": v, "offset": o, "bytes": s} for k, v, o, s in summary.sections],
        "skeletons": [{"nodes": asset.skeleton_info(i)[0], "cm_per_unit": asset.skeleton_info(i)[1]}
                      for i in range(asset.skeleton_count)],
        "clips": clips, "encoder": summary.meta.get("encoder"), "settings": summary.meta.get("settings"),
        "ratio_bvh": raw_total / len(data) if raw_total else None,
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"{printable(info['file'])}: mocodec asset, format {info['format']}, {len(data):,} bytes, ok")
    if info["encoder"]:
        # META is the asset's own text: printed with escapes (JSON's, and printable's).
        print(f"  written by {printable(str(info['encoder']))}, settings {json.dumps(info['settings'])}")
    print(f"  memory to sample: the asset itself ({len(data):,} B, sampled in place) + "
          f"{info['scratch_bytes']:,} B scratch per playing instance")
    if info["ratio_bvh"]:
        print(f"  ratio {info['ratio_bvh']:.1f}:1 vs the source's float32 channels")
    print("  sections: " + ", ".join(f"{printable(s['kind'])} {s['bytes']:,} B" for s in info["sections"]))
    for i, s in enumerate(info["skeletons"]):
        print(f"  skeleton {i}: {s['nodes']} nodes, {s['cm_per_unit']:g} cm per unit")
    print(f"  {'clip':<16} {'codec':<8} {'frames':>7} {'fps':>8} {'seconds':>8} {'skel':>4} {'max cm':>8}")
    for c in clips:
        err = f"{c['max_error_cm']:.4f}" if c["max_error_cm"] is not None else "-"
        print(f"  {printable(c['name']):<16} {c['codec']:<8} {c['frames']:>7} {c['frame_rate']:>8.3f} "
              f"{c['duration_s']:>8.3f} {c['skeleton']:>4} {err:>8}")
    return 0


def _codec_name(codec_id: int) -> str:
    codec = codecs.by_id(codec_id)
    return codec.name if codec else str(codec_id)


def cmd_view(args: argparse.Namespace) -> int:
    """One self-contained page: the asset decoded in the page by the wasm runtime, the originals."""
    from .runtime import Asset, Result, RuntimeResultError, validate
    from .view import build_page, match_originals, read_motions, serve_page

    data = _read_asset(args.asset)
    out = None if args.serve else check_output(args.output or Path(args.asset).with_suffix(".html"),
                                               [args.asset, *(args.original or [])])
    originals = []
    status = validate(data)
    if status != Result.OK:
        print(f"mocodec: warning: {args.asset}: {RuntimeResultError(int(status))}; the page shows this error"
              + (" and compares no original" if args.original else ""), file=sys.stderr)
    else:
        asset = Asset(data)
        clips = [(c.name, c.frame_count, [n.name for n in asset.nodes(c.skeleton)]) for c in asset.clips]
        motions = [(str(p), m) for p in args.original or [] for m in read_motions(p)]
        originals = match_originals(motions, clips)
    html = build_page(data, Path(args.asset).name, originals)
    if args.serve:
        serve_page(html, args.port)
        return 0
    write_atomic(out, html)
    if not args.quiet:
        compared = f"{len(originals)} of {len(clips)} clips compared with an original" if status == Result.OK else "no clip shown"
        print(f"wrote {printable(str(out))} ({len(html.encode()):,} bytes, opens with no network; {compared})")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """Encode the bundled sample clips, decode them through the C runtime, report."""
    samples = Path(__file__).resolve().parent / "samples"
    out_dir = Path(args.output)
    out_dir.mkdir(parents=True, exist_ok=True)
    asset_path = out_dir / "samples.mcd"
    ns = argparse.Namespace(inputs=[str(samples)], codec=args.codec, tolerance=args.tolerance,
                            effector_tolerance=None, units=None, cm_per_unit=None, option=None,
                            quiet=False, json=False)
    motions, result, _ = _encode(ns)
    write_atomic(asset_path, result.asset)
    print(f"encoded {len(motions)} sample clips ({samples}) -> {asset_path}")
    print("\n".join(_summary_lines(result)))
    print("\nper clip:")
    print("\n".join(_clip_table(result)))
    dec = argparse.Namespace(asset=str(asset_path), output=str(out_dir / "decoded"), clip=None,
                             precision=6, quiet=True)
    cmd_decode(dec)
    print(f"\ndecoded every clip through the C runtime back to BVH in {out_dir / 'decoded'}/")
    ok = result.max_error_cm <= args.tolerance
    print(f"tolerance {args.tolerance} cm {'met' if ok else 'NOT met'} on every frame of every clip")
    return 0 if ok else 1


# ----------------------------------------------------------------------------- parser
def _add_encode_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="BVH files (one clip each), glTF 2.0 files (.gltf, .glb: every animation "
                        "a clip) or folders of them")
    p.add_argument("--codec", default=DEFAULT_CODEC, choices=codecs.available(), metavar="CODEC",
                   help="codec, one of: %(choices)s (default: %(default)s, the smallest that "
                        "meets the tolerance: a whole library in one section; spline samples in "
                        "place without resident memory; `mocodec --help` describes each)")
    p.add_argument("-t", "--tolerance", type=float, default=DEFAULT_TOLERANCE_CM, metavar="CM",
                   help="max world-space position error of any joint or end site on any frame, "
                        "in cm (default: %(default)s)")
    p.add_argument("--effector-tolerance", type=float, default=None, metavar="CM",
                   help="a tighter bound for hands, feet, head and end sites, in cm")
    p.add_argument("--pca-variance", type=float, default=None, metavar="F",
                   help="seed 003's own setting instead of a tolerance: codec rma coded as PCA "
                        "of virtual markers per behaviour group keeping this fraction of the "
                        "variance (the paper: 0.95, 0.98); makes no error promise and reports "
                        "the error reached (codec rma-pca)")
    units = p.add_mutually_exclusive_group()
    units.add_argument("--units", choices=["cm", "m", "mm", "in", "cmu"],
                       help="the BVH files' length unit (cmu: CMU mocap, 5.6444 cm); "
                            "default: guessed from the figure's animated poses (glTF is metres)")
    units.add_argument("--cm-per-unit", type=float, metavar="X", help="centimetres per BVH file unit")
    p.add_argument("--strict", action="store_true",
                   help="a BVH figure under 50 or over 300 cm tall in its unit is an error, not a warning")
    p.add_argument("--rate", type=float, default=None, metavar="HZ",
                   help="frames per second glTF clips are resampled at (default: the clip's key "
                        "spacing when regular, subdivided up to 24 Hz, else 60); errors are measured "
                        "against the source's own interpolation at those times")
    p.add_argument("-O", "--option", action="append", metavar="KEY=VALUE",
                   help="a codec setting, e.g. -O block_keys=8 (codec rma) or -O block_shift=6 (codec "
                        "spline); values are JSON; an unknown setting is named with the codec's list")
    p.add_argument("--contacts", action=argparse.BooleanOptionalAction, default=False,
                   help="store foot contact trajectories that the runtime restores by IK "
                        "(MCD_SAMPLE_CONTACTS); errors are measured with them applied "
                        "(default: off)")
    p.add_argument("-j", "--jobs", type=int, default=None, metavar="N",
                   help="clips encoded at once, each in a process of its own (default: one per "
                        "core; 1: one after the other in this process); the asset is the same bytes")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="encode the clips on a running Dask cluster, e.g. tcp://host:8786 (needs "
                        "pip install 'mocodec[cluster]' here and on the workers; docs/CLUSTER.md)")
    p.add_argument("--cache", metavar="DIR",
                   help="keep each encoded clip in this folder and reuse it while the clip, the "
                        "settings and the encoder are unchanged: a re-bake encodes changed clips only")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mocodec",
        description="Compress motion capture (BVH, glTF 2.0) into compact .mcd assets that the mocodec C "
                    "runtime samples inside a game engine, with a promised max error.",
        epilog=EPILOG + "\ncodecs:\n" + _codec_list() + "\n",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"mocodec {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("encode", help="encode BVH or glTF clips into one .mcd asset",
                       description="Encode BVH and glTF clips into one asset; every clip stays addressable by name.")
    _add_encode_arguments(p)
    p.add_argument("-o", "--output", required=True, metavar="OUT.mcd", help="asset to write")
    p.set_defaults(func=cmd_encode)

    p = sub.add_parser("decode", help="decode an asset back to BVH or glTF through the C runtime",
                       description="Decode clips through the C runtime and write BVH with the "
                                   "original hierarchy and channel layout, or glTF 2.0 (-o x.glb / "
                                   "x.gltf: every clip an animation on the original node hierarchy, "
                                   "a key per frame).")
    p.add_argument("asset", metavar="ASSET.mcd")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="a .bvh file (one clip), a folder (one BVH per clip), or a .glb / .gltf "
                        "file (every clip)")
    p.add_argument("--clip", metavar="NAME", help="decode only this clip")
    p.add_argument("--precision", type=int, default=6, help="decimals written (default: %(default)s)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_decode)

    p = sub.add_parser("info", help="describe an asset: clips, sizes, the error the encoder reached",
                       description="Validate an asset and describe it.")
    p.add_argument("asset", metavar="ASSET.mcd")
    p.add_argument("--json", action="store_true", help="print as JSON")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("eval", help="encode, decode through C, report sizes and errors",
                       description="Encode, decode through the C runtime, and report sizes, "
                                   "ratios in both conventions and max/p99/mean error per clip and joint.")
    _add_encode_arguments(p)
    p.add_argument("-o", "--output", metavar="OUT.mcd", help="also write the asset")
    p.add_argument("--sweep", nargs="+", type=float, metavar="CM",
                   help="encode at each of these tolerances and write the size-against-error curve "
                        "(--plot) instead of one report")
    p.add_argument("--codecs", nargs="+", metavar="CODEC",
                   help="with --sweep: the codecs to compare (default: --codec)")
    p.add_argument("--plot", metavar="FILE", help="with --sweep: the curve as a page (.html, default "
                                                  "sweep.html) or a PNG (.png, needs matplotlib)")
    p.set_defaults(func=cmd_eval)

    p = sub.add_parser("view", help="a page that plays an asset beside the original, with its errors",
                       description="Write one self-contained HTML page (no network needed to open it) "
                                   "that decodes the asset in the browser with the runtime compiled to "
                                   "WebAssembly, shows the original and the decoded skeleton with each "
                                   "joint coloured by its error, a timeline, the clip list, the figures "
                                   "and the error per frame; or serve it on localhost.")
    p.add_argument("asset", metavar="ASSET.mcd")
    p.add_argument("--original", nargs="+", metavar="FILE",
                   help="the motions the asset was encoded from (BVH; each matched to the clip of its name)")
    p.add_argument("-o", "--output", metavar="VIEW.html", help="page to write (default: ASSET.html)")
    p.add_argument("--serve", action="store_true", help="serve the page on localhost instead of writing it")
    p.add_argument("--port", type=int, default=0, help="port for --serve (default: any free one)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("demo", help="run the whole pipeline on the sample clips that ship with mocodec",
                       description="Encode the bundled CMU sample clips, decode them through the C "
                                   "runtime, print ratio and error.")
    p.add_argument("--codec", default=DEFAULT_CODEC, choices=codecs.available(), metavar="CODEC",
                   help="codec, one of: %(choices)s (default: %(default)s)")
    p.add_argument("-t", "--tolerance", type=float, default=DEFAULT_TOLERANCE_CM, metavar="CM")
    p.add_argument("-o", "--output", default="out/demo", metavar="DIR",
                   help="where to write the asset and decoded BVH (default: %(default)s)")
    p.set_defaults(func=cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    def terminate(signum, frame):
        raise Terminated()

    try:
        previous = signal.signal(signal.SIGTERM, terminate)
    except ValueError:  # not the main thread (main() called from a thread): no handler
        previous = None
    try:
        with warnings.catch_warnings():
            # Library warnings (numpy, scikit-learn) are not the user's business under -q, and
            # otherwise one line each, not Python's two-line form.
            if getattr(args, "quiet", False) or getattr(args, "json", False):
                warnings.simplefilter("ignore")
            else:
                warnings.showwarning = _one_line_warning
            return args.func(args)
    except KeyboardInterrupt:
        print("mocodec: interrupted; no file was changed by the unfinished step", file=sys.stderr)
        return 130
    except Terminated:
        print("mocodec: terminated; no file was changed by the unfinished step", file=sys.stderr)
        return 143
    except Exception as exc:  # one line for the user; the traceback on request
        if os.environ.get("MOCODEC_DEBUG"):
            raise
        print(f"mocodec: error: {_describe(exc)}", file=sys.stderr)
        return 1
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    text = str(message).splitlines()[0] if str(message) else category.__name__
    print(f"mocodec: warning: {printable(text)}", file=sys.stderr)


def _describe(exc: Exception) -> str:
    from .io import BVHError

    if isinstance(exc, (CliError, BVHError)):
        return str(exc)
    if isinstance(exc, OSError) and exc.filename:
        return f"{printable(str(exc.filename))}: {exc.strerror}"
    if isinstance(exc, OSError) and exc.strerror:
        return f"cannot write or read a file: {exc.strerror}"
    text = str(exc) or type(exc).__name__
    return printable(text.splitlines()[0]) if text else type(exc).__name__


if __name__ == "__main__":
    sys.exit(main())
