#!/usr/bin/env python3
"""Per-model table: ns/eval (f32, f64), ns/sample (f32) from criterion, and the check figures
(worst reciprocity error, furnace max, smallest chi-square p) from `lacquer check --all --json`.

Usage (from the repository root):
    cargo bench -p lacquer --bench eval            # writes target/criterion/...
    cargo run --release -p lacquer-cli -- check --all --json > target/check.json
    python3 bench/report.py target/check.json > docs/models.md
"""
import json
import os
import platform
import subprocess
import sys

ELEMENTS = 1024  # directions per criterion iteration (see rust-core/benches/eval.rs)


def criterion_ns(group, function, root="target/criterion"):
    path = os.path.join(root, group, function, "new", "estimates.json")
    try:
        with open(path) as f:
            return json.load(f)["mean"]["point_estimate"] / ELEMENTS
    except OSError:
        return None


def fmt(x, spec):
    return "–" if x is None else format(x, spec)


def machine():
    cpu = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def main():
    check = json.load(open(sys.argv[1]))
    models = check["models"] if isinstance(check, dict) else check
    rustc = subprocess.run(["rustc", "--version"], capture_output=True, text=True).stdout.strip()
    print("# Models: speed and checks\n")
    print(f"Machine: {machine()}; {rustc}. ns/eval is the mean over 1024 random direction pairs at the")
    print("model's defaults, single thread (criterion). Check figures are the worst over the defaults, the")
    print("model's check sets and random parameter sets (`lacquer check --all`, standard configuration).\n")
    print("| model | reciprocal | energy-cons. | ns/eval f32 | ns/eval f64 | ns/sample f32 | worst reciprocity err | furnace max | χ² min p | f32 vs f64 | result |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in models:
        name, c, s = r["model"], r["claims"], r["summary"]
        yes = lambda b: "yes" if b else "no (reported)"
        print(
            f"| `{name}` | {yes(c['reciprocal'])} | {yes(c['energy_conserving'])} "
            f"| {fmt(criterion_ns(name, 'eval_f32'), '.1f')} | {fmt(criterion_ns(name, 'eval_f64'), '.1f')} "
            f"| {fmt(criterion_ns(name, 'sample_f32'), '.1f')} | {s['worst_reciprocity']:.1e} | {s['furnace_max']:.4f} "
            f"| {s['chi2_min_p']:.3f} | {s['precision_max']:.1e} | {'PASS' if r['passed'] else 'FAIL'} |"
        )
    presets = check.get("presets", []) if isinstance(check, dict) else []
    if presets:
        print("\n## Paint configurations (model only what a scene needs)\n")
        print("| preset | ns/eval f32 | ns/eval f64 | ns/sample f32 | reciprocity err | furnace max | χ² min p | result |")
        print("|---|---|---|---|---|---|---|---|")
        for p in presets:
            rep = p["report"]
            min_p = min((c["p_value"] for c in rep["chi2"]), default=1.0)
            ok = all(v["status"] != "fail" for v in rep["verdicts"])
            g = "paint/" + p["preset"]
            print(
                f"| `{p['preset']}` | {fmt(criterion_ns(g, 'eval_f32'), '.1f')} | {fmt(criterion_ns(g, 'eval_f64'), '.1f')} "
                f"| {fmt(criterion_ns(g, 'sample_f32'), '.1f')} | {rep['reciprocity']['max_relative_error']:.1e} "
                f"| {rep['furnace']['max_albedo']:.4f} | {min_p:.3f} | {'PASS' if ok else 'FAIL'} |"
            )


if __name__ == "__main__":
    main()
