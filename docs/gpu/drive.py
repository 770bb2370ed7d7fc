"""One training run of the project's Trainer on a machine without Pinocchio, Open3D or OMPL
(the lent GPU machine; trimesh travels there as its wheel): the robot's embodiment,
point-cloud kinematics and signature come from a bundle made where Pinocchio is
(make_bundle.py). The step count is set from the
rate measured in the first 90 steps (all inside the warm-up, whose learning rate does not
depend on the step count), the slowest of the concurrent runs, so all end by --deadline with
the same number of steps."""

import argparse
import importlib.util
import json
import pickle
import sys
import time
import types
from pathlib import Path
from types import SimpleNamespace

ap = argparse.ArgumentParser()
ap.add_argument("--model", required=True)
ap.add_argument("--seed", type=int, default=0)
ap.add_argument("--batch", type=int, default=256)
ap.add_argument("--lr", type=float, default=1e-3)
ap.add_argument("--data", default="planning/data/train50k-band")
ap.add_argument("--bundle", default=".gpu/robot.pkl")
ap.add_argument("--out", required=True)
ap.add_argument("--deadline", type=float, required=True)  # epoch s: training ends by then
ap.add_argument("--hard", type=float, default=30.0)  # s past the deadline: stop regardless
ap.add_argument("--rates", required=True)  # folder where the concurrent runs post rates
ap.add_argument("--procs", type=int, default=1)
ap.add_argument("--safety", type=float, default=0.8)
ap.add_argument("--max-steps", type=int, default=1_000_000)
ap.add_argument("--device", default="auto")
ap.add_argument("--force-fake", action="store_true")
a = ap.parse_args()


class Absent(types.ModuleType):
    """A library this machine lacks, imported at module level and never called here: any
    attribute is a placeholder class, so class statements that subclass one still run."""

    def __getattr__(self, attr: str) -> type:
        if attr.startswith("__"):
            raise AttributeError(attr)
        return type(attr, (), {})


FAKED = ("pinocchio", "open3d", "ompl", "ompl.base", "ompl.geometric", "ompl.util")
missing = {n for n in {f.split(".")[0] for f in FAKED} if importlib.util.find_spec(n) is None}
for name in FAKED:
    if a.force_fake or name.split(".")[0] in missing:
        sys.modules[name] = Absent(name)
        parent, _, child = name.rpartition(".")
        if parent:
            setattr(sys.modules[parent], child, sys.modules[name])
sys.path.insert(0, str(Path.cwd()))

import torch  # noqa: E402

import planning.neural.train as T  # noqa: E402
from planning.neural.data import read_manifest  # noqa: E402
from planning.neural.models import ModelCfg  # noqa: E402

with open(a.bundle, "rb") as f:
    b = pickle.load(f)
T.build_embodiment = lambda robot: b["embodiment"]
T.RobotCloud = lambda robot, emb: b["robot_cloud"]
T.robot_signature = lambda robot: b["signature"]
robot = SimpleNamespace(lower=b["lower"], upper=b["upper"], dof=b["dof"])

name = f"{a.model}-s{a.seed}"
t_start = time.time()
step = float(read_manifest(a.data)["settings"]["max_step"])
cfg = T.TrainCfg(
    steps=30,
    batch=a.batch,
    lr=a.lr,
    seed=a.seed,
    device=a.device,
    threads=1,
    val_every=500,
    save_every=10**9,
)
tr = T.Trainer(a.model, robot, a.data, cfg, ModelCfg(step=step, modes=2))
t_loaded = time.time()
print(f"{name}: loaded in {t_loaded - t_start:.1f} s on {tr.device}", flush=True)
rates = Path(a.rates)
rates.mkdir(parents=True, exist_ok=True)
(rates / f"{name}.loaded").write_text("")
while len(list(rates.glob("*.loaded"))) < a.procs and time.time() < a.deadline - 120:
    time.sleep(0.5)  # calibrate while all runs are on the GPU
calib = f"/tmp/calib-{name}.pt"
tr.run(calib)  # 30 steps: CUDA start, first kernels
t1 = time.time()
cfg.steps = 90
tr.run(calib)
rate = 60 / (time.time() - t1)
(rates / f"{name}.json").write_text(json.dumps({"rate": rate}))
print(f"{name}: {rate:.1f} steps/s alone-in-the-crowd", flush=True)
while len(list(rates.glob("*.json"))) < a.procs and time.time() < a.deadline - 60:
    time.sleep(1)
slowest = min(json.loads(p.read_text())["rate"] for p in rates.glob("*.json"))
left = a.deadline - time.time()
steps = min(a.max_steps, 90 + int(left * slowest * a.safety) // 500 * 500)
cfg.steps, cfg.save_every = steps, 2000
tr.history = []
print(f"{name}: slowest {slowest:.1f} steps/s, {left:.0f} s left -> {steps} steps", flush=True)


def guard(step_now: int, entry: dict) -> None:
    print(
        f"{name}: step {step_now} train {entry['train']:.4f} val {entry['val']:.4f} "
        f"t {time.time() - t_start:.0f} s",
        flush=True,
    )
    if time.time() > a.deadline + a.hard:
        raise SystemExit(f"{name}: past the hard deadline at step {step_now}; last save stays")


t2 = time.time()
digest = tr.run(a.out, guard)
print(
    json.dumps(
        {
            "run": name,
            "steps": tr.step,
            "batch": a.batch,
            "lr": a.lr,
            "rate_calib": rate,
            "slowest": slowest,
            "train_s": time.time() - t2,
            "load_s": t_loaded - t_start,
            "final": tr.history[-1],
            "sha256": digest,
            "device": str(tr.device),
            "gpu": torch.cuda.get_device_name() if torch.cuda.is_available() else None,
        }
    ),
    flush=True,
)
