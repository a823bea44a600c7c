"""``vishap bench all``: run every other benchmark at a quick setting into one folder with an index.

Each benchmark runs as its own process (``python -m vishap bench NAME --out OUT/NAME ...``) so that
one failing or slow benchmark cannot take the others down; its JSON record and every chart it
wrote are linked from ``OUT/index.md`` and ``OUT/index.html``. The quick setting of a benchmark is
its module-level ``QUICK_ARGS`` (a list of command-line words) when it defines one, else its
defaults.
"""
from __future__ import annotations

import html
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HELP = "run every benchmark at a quick setting; write OUT/index.md and OUT/index.html linking all charts"

__all__ = ["HELP", "add_arguments", "run", "bench_names", "write_index"]


def add_arguments(parser) -> None:
    parser.add_argument("--only", default=None, help="comma-separated benchmark names (default: all)")
    parser.add_argument("--skip", default="", help="comma-separated benchmark names to leave out")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds allowed per benchmark (default 900)")
    parser.add_argument("--full", action="store_true", help="run each benchmark at its defaults, not QUICK_ARGS")


def bench_names() -> dict[str, object]:
    from vishap.cli.bench import _bench_modules

    return {k: m for k, m in _bench_modules().items() if k != "all"}


#: Quick settings for benchmarks that define neither ``QUICK_ARGS`` nor a ``--quick`` flag.
QUICK_FALLBACK = {
    "registration": ["--trials", "30"],
    "robot": ["--ticks", "3000", "--rounds", "3"],
    "tactile": ["--seconds", "1.5", "--repeats", "1"],
    "world": ["--approaches", "20"],
    "servo_quality": ["--seeds", "0", "--seconds", "1.5"],
}


def quick_args(name: str, mod) -> list[str]:
    """The quick setting of one benchmark: its ``QUICK_ARGS``, else ``--quick`` if it has that flag,
    else :data:`QUICK_FALLBACK` (only options the benchmark accepts), else nothing (its defaults)."""
    import argparse

    if hasattr(mod, "QUICK_ARGS"):
        return list(mod.QUICK_ARGS)
    p = argparse.ArgumentParser(add_help=False)
    mod.add_arguments(p)
    flags = {o for a in p._actions for o in a.option_strings}
    if "--quick" in flags:
        return ["--quick"]
    extra = QUICK_FALLBACK.get(name, [])
    if any(w.startswith("--") and w not in flags for w in extra):
        return []
    return list(extra)


def _run_one(name: str, mod, out: Path, *, quick: bool, timeout: float) -> dict:
    sub = out / name
    sub.mkdir(parents=True, exist_ok=True)
    extra = quick_args(name, mod) if quick else []
    cmd = [sys.executable, "-m", "vishap", "bench", name, "--out", str(sub), *extra]
    env = dict(os.environ)
    env.setdefault("PYOPENGL_PLATFORM", "egl")
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
        rc, err = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired as exc:
        rc, err = None, f"timed out after {timeout:.0f} s\n{exc.stderr or ''}"
    wall = time.perf_counter() - t0
    (sub / "stderr.txt").write_text(err or "")
    return {
        "name": name,
        "command": " ".join(cmd[3:]),
        "ok": rc == 0,
        "returncode": rc,
        "wall_s": round(wall, 2),
        "error": None if rc == 0 else (err or "").strip().splitlines()[-1:] or ["failed"],
    }


def _headline(record_path: Path, limit: int = 8) -> list[tuple[str, object]]:
    """The first scalar fields of a benchmark's JSON record, for the index."""
    try:
        rec = json.loads(record_path.read_text())
    except (OSError, ValueError):
        return []
    out = []
    for k, v in rec.items():
        if isinstance(v, (int, float, bool)) or (isinstance(v, str) and len(v) < 40):
            out.append((k, v))
        if len(out) >= limit:
            break
    return out


def write_index(out: Path, results: list[dict]) -> tuple[Path, Path]:
    """Write ``index.md`` and ``index.html`` linking each benchmark's charts and JSON files."""
    md = ["# vishap benchmarks", "", f"Generated {time.strftime('%Y-%m-%d %H:%M:%S UTC', time.gmtime())}.", ""]
    md += ["| benchmark | status | wall (s) | command |", "|---|---|---|---|"]
    for r in results:
        status = "ok" if r["ok"] else f"FAILED ({'; '.join(r['error'] or [])})"
        md.append(f"| [{r['name']}](#{r['name']}) | {status} | {r['wall_s']} | `{r['command']}` |")
    body = ["<!doctype html><meta charset='utf-8'><title>vishap benchmarks</title>",
            "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}img{max-width:100%;border:1px solid #ccc}"
            "td,th{padding:2px 8px}.fail{color:#b00}</style>", "<h1>vishap benchmarks</h1><table>",
            "<tr><th>benchmark</th><th>status</th><th>wall (s)</th></tr>"]
    for r in results:
        cls = "" if r["ok"] else " class='fail'"
        body.append(f"<tr><td><a href='#{r['name']}'>{r['name']}</a></td><td{cls}>{'ok' if r['ok'] else 'FAILED'}"
                    f"</td><td>{r['wall_s']}</td></tr>")
    body.append("</table>")
    for r in results:
        sub = out / r["name"]
        charts = sorted(p.relative_to(out) for p in sub.rglob("*") if p.suffix.lower() in (".png", ".svg"))
        jsons = sorted(p.relative_to(out) for p in sub.rglob("*.json"))
        md += ["", f"## {r['name']}", "", f"`vishap {r['command']}` — {'ok' if r['ok'] else 'FAILED'}, {r['wall_s']} s", ""]
        body.append(f"<h2 id='{r['name']}'>{html.escape(r['name'])}</h2><p><code>vishap {html.escape(r['command'])}</code>"
                    f" — {'ok' if r['ok'] else 'FAILED: ' + html.escape('; '.join(r['error'] or []))}, {r['wall_s']} s</p>")
        head = _headline(sub / f"{r['name']}.json")
        if head:
            md += ["| field | value |", "|---|---|"] + [f"| {k} | {v} |" for k, v in head] + [""]
            body.append("<table>" + "".join(f"<tr><td>{html.escape(str(k))}</td><td>{html.escape(str(v))}</td></tr>"
                                            for k, v in head) + "</table>")
        for j in jsons:
            md.append(f"- data: [{j.as_posix()}]({j.as_posix()})")
            body.append(f"<p>data: <a href='{html.escape(j.as_posix())}'>{html.escape(j.as_posix())}</a></p>")
        if not r["ok"]:
            md.append(f"- log: [{r['name']}/stderr.txt]({r['name']}/stderr.txt)")
            body.append(f"<p>log: <a href='{r['name']}/stderr.txt'>stderr.txt</a></p>")
        for c in charts:
            md += ["", f"![{c.as_posix()}]({c.as_posix()})"]
            body.append(f"<p><img src='{html.escape(c.as_posix())}' alt='{html.escape(c.as_posix())}'><br>"
                        f"<small>{html.escape(c.as_posix())}</small></p>")
    md_path = out / "index.md"
    html_path = out / "index.html"
    md_path.write_text("\n".join(md) + "\n")
    html_path.write_text("\n".join(body) + "\n")
    return md_path, html_path


def run(args) -> dict:
    out = Path(args.out)
    mods = bench_names()
    names = list(mods)
    if args.only:
        wanted = [n.strip() for n in args.only.split(",") if n.strip()]
        unknown = [n for n in wanted if n not in mods]
        if unknown:
            from vishap._core.errors import ConfigError

            raise ConfigError(f"unknown benchmark(s) {unknown}; available: {sorted(mods)}", field="--only")
        names = wanted
    skip = {n.strip() for n in args.skip.split(",") if n.strip()}
    names = [n for n in names if n not in skip]
    from vishap._core.results import progress

    results = []
    bar = progress(names, desc="bench all", unit="bench", quiet=getattr(args, "quiet", False))
    for name in bar:
        bar.write(f"bench all: {name} ...", file=sys.stderr)  # a line per benchmark also in a log
        results.append(_run_one(name, mods[name], out, quick=not args.full, timeout=args.timeout))
    md_path, html_path = write_index(out, results)
    return {
        "benchmarks": len(results),
        "ok": sum(r["ok"] for r in results),
        "failed": [r["name"] for r in results if not r["ok"]],
        "index_md": str(md_path),
        "index_html": str(html_path),
        "results": results,
    }
