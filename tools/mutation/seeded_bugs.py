"""The bugs of the seeded-bug table in docs/TESTING.md, seeded one at a time: each must fail its
named test.

Each bug is a one-line source edit applied to a scratch copy of the packages
(``build/mutation/_seeded/``, put first on PYTHONPATH; the checkout is never edited); the named
tests run against it and must fail. Prints one line per bug (CAUGHT / MISSED) and exits 1 if
any is missed. Usage (from the repository root): ``vega-env python tools/mutation/seeded_bugs.py``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
STAGE = ROOT / "build" / "mutation" / "_seeded"

# (bug, package-relative file, original text, bug text, tests that must fail)
BUGS = [
    ("certificate accepts an indefinite closed-loop Lyapunov matrix",
     "offline/vega_lpv/certificate.py",
     "-np.linalg.eigvalsh(0.5 * (P_cl + P_cl.T))[0])", "-np.inf)",
     ["tests/lpv/test_certificate_negative.py::test_non_positive_lyapunov_matrix_is_rejected"]),
    ("negative command beyond -6.5 deg not flagged LIMITED",
     "vega_gnc/controller_runtime.py", "if abs(u) > lim:", "if u > lim:",
     ["tests/gnc/test_controller_runtime_limits.py::test_saturation_both_ways"]),
    ("x_cg deviation applied with the wrong sign",
     "vega_model/parameters.py", 'x_cg_m=self.x_cg_m * (1.0 + d["x_cg"])',
     'x_cg_m=self.x_cg_m * (1.0 - d["x_cg"])',
     ["tests/model/test_uncertainty_perturbation.py::test_each_deviation_alone"]),
    ("Q not recomputed from the perturbed velocity and density",
     "vega_model/parameters.py", "q = 0.5 * rho * v * v\n        s1", "q = self.q_pa\n        s1",
     ["tests/model/test_uncertainty_perturbation.py::test_hand_numbers_for_velocity_and_density"]),
    ("phase margin of the synthesis report given as 180 deg - PM",
     "offline/vega_lpv/verification.py", "margin = np.degrees(np.abs(np.angle(-L[k])))",
     "margin = 180.0 - np.degrees(np.abs(np.angle(-L[k])))",
     ["tests/lpv/test_margins_reference.py::test_open_loop_stable_textbook_loop"]),
    ("bending peak of the synthesis report taken as the minimum in its window",
     "offline/vega_lpv/verification.py", "(w_radps < 1.2 * w0)].max()",
     "(w_radps < 1.2 * w0)].min()",
     ["tests/lpv/test_margins_reference.py::test_bending_peaks_are_the_maximum_in_each_window"]),
    ("replay --check-controller IDENTICAL with more commands than the bag",
     "vega_bags/replay.py", "if len(recorded) != len(replayed):",
     "if len(recorded) > len(replayed):",
     ["tests/bags/test_replay_length.py::test_more_commands_than_the_bag_are_a_difference",
      "tests/bags/test_replay_length.py::test_check_with_more_commands_than_the_bag_is_different"]),
]


def _packages():
    found = {p.name: p / p.name for p in (ROOT / "ros2_ws" / "src").iterdir()
             if (p / p.name / "__init__.py").is_file()}
    found.update({p.name: p for base in ("offline", "cli") for p in (ROOT / base).iterdir()
                  if (p / "__init__.py").is_file()})
    return found


def main() -> int:
    """Seed each bug, run its tests, report; exit 1 if a bug is not caught."""
    if STAGE.exists():
        shutil.rmtree(STAGE)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    pkgs = _packages()
    for name, src in pkgs.items():
        shutil.copytree(src, STAGE / name, ignore=ignore, symlinks=True)
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(STAGE), os.environ.get("PYTHONPATH", "")]))
    baseline = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                               *sorted({t for *_, tests in BUGS for t in tests})], cwd=ROOT,
                              env=env, capture_output=True, text=True, check=False)
    if baseline.returncode != 0:
        print(f"baseline: the named tests fail without any seeded bug (pytest exit "
              f"{baseline.returncode})\n{baseline.stdout[-2000:]}")
        return 1
    print("baseline: the named tests pass on the unmodified copy", flush=True)
    missed = 0
    for bug, rel, old, new, tests in BUGS:
        pkg, _, _ = rel.partition("/")
        original = (pkgs[pkg].parent / rel).read_text()
        if original.count(old) < 1:
            print(f"STALE   {bug}: '{old}' not in {rel} (update tools/mutation/seeded_bugs.py)")
            missed += 1
            continue
        (STAGE / rel).write_text(original.replace(old, new, 1))
        proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider",
                               *tests], cwd=ROOT, env=env, capture_output=True, text=True,
                              check=False)
        (STAGE / rel).write_text(original)
        caught = proc.returncode == 1
        missed += not caught
        print(f"{'CAUGHT' if caught else 'MISSED'}  {bug}: {' '.join(tests)} "
              f"(pytest exit {proc.returncode})", flush=True)
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
