#!/usr/bin/python3
"""Simulates the seed study's cohort (PAPER.md) for `clearfit study`: participants with
person-to-person skin variation (SKIN.md ranges), the eight bump conditions (2, 3, 4, 5 mm
wide x 1, 2 mm high, acrylic in index-matching oil), trials of the study's protocol (4 s
above the bump, 3 s pressed; as two videos, so a press too light to blanch is still assessed), each with its own force, and a per-person
pressure calibration from simulated presses. Writes OUT/study.yaml; then:

    clearfit study run OUT/study.yaml --out OUT/results

Usage: scripts/simulate-cohort.py OUT [--participants 8] [--trials 5] [--scale 0.5]
       [--fps 30] [--seed 1] [--clearfit build/cli/clearfit]
Every simulated parameter (skin, force) is recorded in OUT/cohort-truth.json."""
import argparse
import json
import os
import random
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PLATE = os.path.join(ROOT, "samples", "study-plate")
CONDITIONS = [(d, h) for h in (1, 2) for d in (2, 3, 4, 5)]  # the study's eight: width x height, mm


def person(rng, k):
    """A participant's skin, drawn from SKIN.md's ranges."""
    return {"tone": rng.choice(["light", "medium", "dark"]), "s50_kpa": round(rng.uniform(6, 11), 2),
            "width_kpa": round(rng.uniform(1.5, 3.0), 2), "beta": round(rng.uniform(0.65, 0.95), 3),
            "von_mises_weight": round(rng.uniform(0.4, 0.8), 2), "id": f"p{k + 1}"}


def scene(mesh, window):
    """The condition's scene (the study-plate sample's, with this condition's mesh)."""
    return (f"mesh: {mesh}\nunits: mm\nior: 1.490\nmedium_ior: 1.498\nskin_ior: 1.4\ncontact: {{group: contact}}\n"
            f"camera: camera.cameramodel\nmap: {{normals: smooth, mode: adaptive, grid_step: 32, tolerance_um: 1.0, chart: lscm}}\n"
            f"captures: {{window_frames: {window}}}\nassess: {{smoothing_mm: 0.1, thresholds_kpa: [4.3, 5.5]}}\n"
            f"outputs: {{texel_mm: 0.02}}\n"
            # The finger floats flat above the bump before the press: one map serves both phases
            # (the held model would wrap the bump's wall), as in the study-plate sample.
            f"baseline: {{part: touching}}\n")


def simulation(p, d, h, force, seed, args, presses):
    skin = ", ".join(f"{k}: {v}" for k, v in p.items() if k != "id")
    return (f"simulation:\n  seed: {seed}\n  scale: {args.scale}\n  format: huffyuv\n"
            f"  timeline: {{fps: {args.fps}, baseline_s: 4, press_s: 3}}\n  skin: {{{skin}}}\n"
            f"  baseline: {{part: touching}}\n"
            f"  pressure:\n    texel_mm: 0.02\n    sources:\n"
            f"      - {{name: bump, type: punch, center_part_mm: [0, 0, {-h}], radius_mm: {d / 2}, force_n: {force:.5f}}}\n"
            + (f"  presses: {{diameters_mm: [2, 3, 4, 5], levels: 9, repetitions: 3}}\n" if presses else ""))


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"failed: {' '.join(cmd)}\n{r.stderr}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--participants", type=int, default=8)
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--conditions", type=int, default=8, help="the first N of the eight conditions")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--fps", type=float, default=30)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--clearfit", default=os.path.join(ROOT, "build", "cli", "clearfit"))
    ap.add_argument("--run", action="store_true", help="then run the study (clearfit study run) into OUT/results")
    ap.add_argument("--jobs", type=int, default=1, help="with --run: parallel jobs")
    args = ap.parse_args()
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    rng = random.Random(args.seed)
    people = [person(rng, k) for k in range(args.participants)]
    conditions = CONDITIONS[: args.conditions]
    window = int(args.fps * 2)  # 2 s of each phase (the study: 100 frames at 60 fps)
    cond_entries, trial_entries, truth = [], [], {"participants": people, "trials": []}
    for d, h in conditions:
        cid = f"d{d}-h{h}"
        cdir = os.path.join(out, cid)
        os.makedirs(cdir, exist_ok=True)
        run(["/usr/bin/python3", os.path.join(PLATE, "make_mesh.py"), "--radius", str(d / 2), "--height", str(h),
             "--out", os.path.join(cdir, "plate.obj")])
        with open(os.path.join(cdir, "scene.yaml"), "w") as f:
            f.write(scene("plate.obj", window))
        cond_entries.append(f"  - {{id: {cid}, scene: {cid}/scene.yaml, bump: {{diameter_mm: {d}, height_mm: {h}}}}}")
    done, total = 0, len(people) * len(conditions) * args.trials
    for p in people:
        for ci, (d, h) in enumerate(conditions):
            cid = f"d{d}-h{h}"
            for t in range(args.trials):
                tid = f"{p['id']}-{cid}-{t + 1}"
                tdir = os.path.join(out, p["id"], tid)
                os.makedirs(tdir, exist_ok=True)
                mean_kpa = rng.uniform(4, 24)  # the trial's mean pressure under the bump
                force = mean_kpa * 3.141592653589793 * (d / 2) ** 2 / 1000
                seed = rng.randrange(1, 2**31)
                first = ci == 0 and t == 0
                with open(os.path.join(tdir, "sim.yaml"), "w") as f:
                    f.write(scene(os.path.join(out, cid, "plate.obj"), window).replace(
                        "camera: camera.cameramodel", f"camera: {os.path.join(PLATE, 'camera.cameramodel')}"))
                    f.write(simulation(p, d, h, force, seed, args, first))
                run([args.clearfit, "simulate", os.path.join(tdir, "sim.yaml"), "--out", tdir, "--quiet"]
                    + ([] if first else ["--no-presses"]))
                if first:  # the scaled camera of this resolution, for every condition's scene
                    for c2 in conditions:
                        with open(os.path.join(tdir, "camera.cameramodel")) as src, \
                                open(os.path.join(out, f"d{c2[0]}-h{c2[1]}", "camera.cameramodel"), "w") as dst:
                            dst.write(src.read())
                    run([args.clearfit, "calibrate-pressure", "--presses", os.path.join(tdir, "presses.csv"), "--person",
                         p["id"], "--camera", os.path.join(tdir, "camera.cameramodel"), "--out",
                         os.path.join(out, p["id"], "calibration.json")])
                trial_entries.append(f"  - {{id: {tid}, participant: {p['id']}, condition: {cid}, "
                                     f"baseline: {p['id']}/{tid}/baseline.mkv, worn: {p['id']}/{tid}/worn.mkv, force_n: {force:.5f}}}")
                truth["trials"].append({"id": tid, "mean_pressure_kpa": mean_kpa, "force_n": force, "seed": seed})
                done += 1
                print(f"\r{done}/{total} trials simulated", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    with open(os.path.join(out, "study.yaml"), "w") as f:
        f.write(f"schema: clearfit.study/1\nstudy: simulated-cohort\nparticipants:\n")
        f.writelines(f"  - {{id: {p['id']}, calibration: {p['id']}/calibration.json}}\n" for p in people)
        f.write("conditions:\n" + "\n".join(cond_entries) + "\ntrials:\n" + "\n".join(trial_entries) + "\n")
        f.write("analysis: {pressure: true}\n")
    with open(os.path.join(out, "cohort-truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    print(f"wrote {os.path.join(out, 'study.yaml')}: {len(people)} participants x {len(conditions)} conditions x "
          f"{args.trials} trials; run: clearfit study run {os.path.join(out, 'study.yaml')} --out {os.path.join(out, 'results')}")
    if args.run:  # the study itself, with its progress on stderr; its exit code says whether some trials failed
        sys.exit(subprocess.run([args.clearfit, "study", "run", os.path.join(out, "study.yaml"), "--out",
                                 os.path.join(out, "results"), "--jobs", str(args.jobs)]).returncode)


if __name__ == "__main__":
    main()
