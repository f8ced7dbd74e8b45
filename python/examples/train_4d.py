"""Trains bettimill.torch.BettiNet4d on CPU to predict the Betti numbers of 4D images.

The samples are made on the fly by bettimill.torch.SyntheticDataset (no shards on disk):
the train split to learn from, the test split to score. Objects in empty space and cavities
carved from a solid 4-cube, with one or two copies, make every Betti number vary: b0 counts
the objects, b3 the cavities, b1 and b2 tell the families apart. Each b_k that varies in the
train split is scored as a class against the majority baseline (always answering the train
split's most common b_k; a b_k that never varies is reported as such and not scored), and
the whole vector likewise ("all four right" against the most common vector).

    python python/examples/train_4d.py                  # the default: 3 families, 4D side 16
    python python/examples/train_4d.py --tiny --json    # the configuration python/tests runs

Prints per-Betti accuracy and baseline; with --json, one JSON line at the end as well.
"""

import argparse
import json
import time

import torch

import bettimill
from bettimill.torch import BettiNet4d, SyntheticDataset, betti_targets

MANIFEST = """\
schema_version = 1
name = "train-4d"
dimension = 4
side = {side}
mode = ["embed", "carve"]
components = {components}
samples = {samples}
shard_size = {samples}
seed = {seed}

[splits]
train = {train}
test = {test}

[[classes]]
family = {families}
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tiny", action="store_true", help="the default families and copies, 64 samples, 10 epochs")
    parser.add_argument("--families", default="ball,handle,s2_x_b2", help="comma-separated 4D families")
    parser.add_argument("--components", default="1,2", help="copies of the object (cavities when carved) per sample")
    parser.add_argument("--side", type=int, default=16)
    parser.add_argument("--train", type=int, default=240)
    parser.add_argument("--test", type=int, default=60)
    parser.add_argument("--epochs", type=int, default=8)
    parser.add_argument("--batch", type=int, default=8)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=0, help="DataLoader worker processes")
    parser.add_argument("--json", action="store_true", help="print a JSON summary line")
    args = parser.parse_args()
    if args.tiny:
        args.families, args.train, args.test, args.epochs, args.batch = "ball,handle,s2_x_b2", 48, 16, 10, 4

    torch.manual_seed(args.seed)
    # One thread: the same seed gives the same numbers on any machine.
    torch.set_num_threads(1)
    families = json.dumps(args.families.split(","))
    components = json.dumps([int(c) for c in args.components.split(",")])
    text = MANIFEST.format(families=families, components=components, side=args.side, samples=args.train + args.test, seed=args.seed, train=args.train, test=args.test)
    plan = bettimill.Plan(text)
    max_betti = 2
    loader = lambda split, shuffle: torch.utils.data.DataLoader(
        SyntheticDataset(plan, split=split, transform=betti_targets),
        batch_size=args.batch,
        shuffle=shuffle,
        num_workers=args.workers,
        generator=torch.Generator().manual_seed(args.seed),
    )
    # Made once and kept: every epoch sees the same samples (they are a pure function of the
    # plan), so generating them again would only cost time.
    started = time.time()
    train = list(loader("train", False))
    test = list(loader("test", False))
    made = time.time() - started

    model = BettiNet4d(dimension=4, max_betti=max_betti, width=4)
    optimiser = torch.optim.Adam(model.parameters(), lr=3e-3)
    for epoch in range(args.epochs):
        order = torch.randperm(len(train), generator=torch.Generator().manual_seed(args.seed + epoch))
        total = 0.0
        for i in order.tolist():
            images, betti = train[i]
            logits = model(images)
            loss = torch.nn.functional.cross_entropy(logits.reshape(-1, max_betti + 1), betti.clamp(max=max_betti).reshape(-1))
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item()
        print(f"epoch {epoch + 1}/{args.epochs}: loss {total / len(train):.4f}")

    model.eval()
    with torch.no_grad():
        predicted = torch.cat([model(images).argmax(dim=2) for images, _ in test])
    truth = torch.cat([betti.clamp(max=max_betti) for _, betti in test])
    train_truth = torch.cat([betti.clamp(max=max_betti) for _, betti in train])
    accuracy, baseline, varies = [], [], []
    for k in range(4):
        counts = torch.bincount(train_truth[:, k], minlength=max_betti + 1)
        majority = counts.argmax()
        varies.append(bool((counts > 0).sum() > 1))
        accuracy.append((predicted[:, k] == truth[:, k]).float().mean().item())
        baseline.append((truth[:, k] == majority).float().mean().item())
        if varies[k]:
            print(f"b{k}: accuracy {accuracy[k]:.3f}  majority baseline {baseline[k]:.3f}")
        else:
            print(f"b{k}: always {majority.item()} in the train split, not scored")
    vectors, counts = torch.unique(train_truth, dim=0, return_counts=True)
    common = vectors[counts.argmax()]
    exact = (predicted == truth).all(dim=1).float().mean().item()
    exact_baseline = (truth == common).all(dim=1).float().mean().item()
    print(f"all four right: {exact:.3f}  baseline (always {common.tolist()}) {exact_baseline:.3f}")
    print(f"samples made in {made:.1f} s, total {time.time() - started:.1f} s")
    if args.json:
        summary = {"accuracy": accuracy, "baseline": baseline, "varies": varies, "exact": exact, "exact_baseline": exact_baseline}
        print(json.dumps(summary))


if __name__ == "__main__":
    main()
