"""``python -m generator --seeds 0 137 281``: the main job."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _int_at_least(minimum: int, what: str):
    """An argparse type: an integer >= ``minimum``, with a one-line error otherwise."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < minimum:
            raise argparse.ArgumentTypeError(f"{what} must be an integer >= {minimum}, got {text!r}")
        return value

    return parse


_seed = _int_at_least(0, "seed")
_positive = _int_at_least(1, "value")


def parse_args(argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(
        prog="python -m generator",
        description="Build one site per seed and explore it with the Simulator (interim demo: "
        "the full dataset export arrives with the batch generator).",
    )
    p.add_argument("--seeds", type=_seed, nargs="+", default=[0, 137, 281], help="scene seeds (default: 0 137 281)")
    p.add_argument("--out", type=Path, default=Path("output"), help="output folder (default: ./output)")
    p.add_argument("--steps", type=_positive, default=100, help="random-walk steps per seed (default: 100)")
    return p.parse_args(argv)


def main(argv=None) -> int:
    args = parse_args(argv)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
        probe = args.out / ".write-test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        print(f"error: cannot write to output folder {args.out}: {exc.strerror}", file=sys.stderr)
        return 2
    from tqdm import tqdm

    from .demo import run_seed

    failed = 0
    with tqdm(total=len(args.seeds) * args.steps, desc="steps", unit="step") as bar:
        for seed in args.seeds:
            try:
                r = run_seed(seed, args.out, args.steps, bar)
            except Exception as exc:  # report and continue with the other seeds
                failed += 1
                tqdm.write(f"seed {seed}: FAILED: {exc}")
                continue
            tqdm.write(
                f"seed {seed}: {r['points']:,} points, final coverage {r['coverage'][-1]:.3f}, "
                f"AUC {r['auc']:.3f}, {r['seconds']:.1f} s -> {args.out / f'seed_{seed:06d}'}"
            )
    return 1 if failed else 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        sys.exit(130)
