"""Train the shipped rebar segmentation model on synthetic captures, on the CPU, and export it.

Steps (each resumable, outputs under ``--work``):

    python training/train_segmentation.py data   --work /tmp/seg   # render the 6:2:2 data set
    python training/train_segmentation.py train  --work /tmp/seg --arch unet    --minutes 18
    python training/train_segmentation.py train  --work /tmp/seg --arch deeplab --minutes 18
    python training/train_segmentation.py export --work /tmp/seg --arch unet --out rebarlib/models

The data set is ``rebarlib.segmentation.synth_segmentation_capture(i)`` for
``i < DATASET_SIZE``, rendered at 640 x 400 (``GEMINI2.scaled(0.5)``); the split is
``rebarlib.segmentation.split_indices()`` (by capture, seeded). The models see the colour image
resized to 640 x 400 and return one rebar logit per pixel at that size; at run time the logit
map is resized bilinearly to the capture's full resolution and thresholded at 0 (p = 0.5).

torch is used only here (``pip install rebarlib[train]``); the runtime uses onnxruntime.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

IN_W, IN_H = 640, 400
MEAN = [123.7, 116.3, 103.5]  # RGB, 0-255 units
STD = [58.4, 57.1, 57.4]
TRAIN_SEED = 7


# ---------------------------------------------------------------------------------------------
# data


def cmd_data(args):
    from rebarlib import GEMINI2
    from rebarlib.segmentation import DATASET_SEED, split_indices, synth_segmentation_capture

    work = Path(args.work)
    (work / "data").mkdir(parents=True, exist_ok=True)
    split = split_indices(args.n, seed=DATASET_SEED)
    wanted = sorted(int(i) for k in ("train", "val") for i in split[k])
    t0 = time.time()
    for n, i in enumerate(wanted):
        f = work / "data" / f"{i:04d}.npz"
        if f.exists():
            continue
        cap = synth_segmentation_capture(i, seed=DATASET_SEED, intrinsics=GEMINI2.scaled(0.5))
        np.savez_compressed(f, color=cap.color, mask=cap.labels > 0)
        if n % 20 == 0:
            print(f"{n}/{len(wanted)} {time.time() - t0:.0f} s", flush=True)
    (work / "split.json").write_text(json.dumps({k: [int(i) for i in v] for k, v in split.items()}))
    print("done", time.time() - t0)


def _load(work: Path, part: str):
    split = json.loads((work / "split.json").read_text())
    imgs, masks = [], []
    for i in split[part]:
        z = np.load(work / "data" / f"{i:04d}.npz")
        imgs.append(z["color"])
        masks.append(z["mask"])
    return np.stack(imgs), np.stack(masks)


# ---------------------------------------------------------------------------------------------
# models


def build_model(arch: str):
    import torch
    from torch import nn
    import torch.nn.functional as F

    def cbr(cin, cout, k=3, s=1, d=1):
        return nn.Sequential(nn.Conv2d(cin, cout, k, s, padding=d * (k // 2), dilation=d, bias=False),
                             nn.BatchNorm2d(cout), nn.ReLU(inplace=True))

    def ds(cin, cout, s=1, d=1):
        # depthwise-separable conv (MobileNet-style light backbone)
        return nn.Sequential(nn.Conv2d(cin, cin, 3, s, padding=d, dilation=d, groups=cin, bias=False),
                             nn.BatchNorm2d(cin), nn.ReLU(inplace=True),
                             nn.Conv2d(cin, cout, 1, bias=False), nn.BatchNorm2d(cout), nn.ReLU(inplace=True))

    def up(x, ref):
        return F.interpolate(x, size=ref.shape[-2:], mode="bilinear", align_corners=False)

    class UNetSmall(nn.Module):
        """Encoder to 1/8 of the input, decoder with skips back to the input resolution."""

        def __init__(self):
            super().__init__()
            self.full = cbr(3, 8)
            self.e1 = nn.Sequential(cbr(3, 16, s=2), cbr(16, 16))
            self.e2 = nn.Sequential(cbr(16, 32, s=2), cbr(32, 32))
            self.e3 = nn.Sequential(cbr(32, 64, s=2), cbr(64, 64), cbr(64, 64, d=2), cbr(64, 64, d=4))
            self.d2 = cbr(96, 32)
            self.d1 = cbr(48, 16)
            self.d0 = cbr(24, 8)
            self.head = nn.Conv2d(8, 1, 1)

        def forward(self, x):
            f0 = self.full(x)
            f1 = self.e1(x)
            f2 = self.e2(f1)
            f3 = self.e3(f2)
            y = self.d2(torch.cat([up(f3, f2), f2], 1))
            y = self.d1(torch.cat([up(y, f1), f1], 1))
            y = self.d0(torch.cat([up(y, f0), f0], 1))
            return self.head(y)

    class DeepLabLite(nn.Module):
        """DeepLabV3+-style: separable backbone to 1/16, ASPP, decoder at 1/4, bilinear to input."""

        def __init__(self):
            super().__init__()
            self.stem = cbr(3, 16, s=2)
            self.l1 = nn.Sequential(ds(16, 24, s=2), ds(24, 24))
            self.l2 = nn.Sequential(ds(24, 48, s=2), ds(48, 48))
            self.l3 = nn.Sequential(ds(48, 96, s=2), ds(96, 96), ds(96, 96, d=2))
            self.a0 = cbr(96, 48, k=1)
            self.a1 = ds(96, 48, d=2)
            self.a2 = ds(96, 48, d=4)
            self.a3 = ds(96, 48, d=8)
            self.pool = nn.Sequential(nn.AdaptiveAvgPool2d(1), nn.Conv2d(96, 48, 1), nn.ReLU(inplace=True))
            self.proj = cbr(240, 64, k=1)
            self.low = cbr(24, 16, k=1)
            self.dec = nn.Sequential(ds(80, 48), ds(48, 48))
            self.head = nn.Conv2d(48, 1, 1)

        def forward(self, x):
            s = self.stem(x)
            low = self.l1(s)
            f = self.l3(self.l2(low))
            g = self.pool(f).expand(-1, -1, f.shape[2], f.shape[3])
            a = self.proj(torch.cat([self.a0(f), self.a1(f), self.a2(f), self.a3(f), g], 1))
            y = self.dec(torch.cat([up(a, low), self.low(low)], 1))
            return up(self.head(y), x)

    return {"unet": UNetSmall, "deeplab": DeepLabLite}[arch]()


# ---------------------------------------------------------------------------------------------
# training


def _normalise(img_u8):
    import torch

    x = torch.from_numpy(img_u8).float().permute(0, 3, 1, 2)
    mean = torch.tensor(MEAN).view(1, 3, 1, 1)
    std = torch.tensor(STD).view(1, 3, 1, 1)
    return (x - mean) / std


def _batch(imgs, masks, rng, size, bs):
    import cv2

    n, H, W = masks.shape
    xb = np.empty((bs, size, size, 3), np.uint8)
    yb = np.empty((bs, size, size), np.float32)
    for k in range(bs):
        i = rng.integers(n)
        y0, x0 = rng.integers(0, H - size + 1), rng.integers(0, W - size + 1)
        im = imgs[i, y0:y0 + size, x0:x0 + size].astype(np.float32)
        m = masks[i, y0:y0 + size, x0:x0 + size]
        if rng.random() < 0.5:
            im, m = im[:, ::-1], m[:, ::-1]
        if rng.random() < 0.5:
            im, m = im[::-1], m[::-1]
        if rng.random() < 0.5:
            im, m = im.transpose(1, 0, 2), m.T
        # photometric jitter beyond the renderer's own: gain per channel, gamma, slight blur
        im = im * rng.uniform(0.85, 1.15, 3) * rng.uniform(0.8, 1.2)
        im = 255 * (np.clip(im, 0, 255) / 255) ** rng.uniform(0.8, 1.25)
        if rng.random() < 0.3:
            im = cv2.GaussianBlur(np.ascontiguousarray(im), (0, 0), rng.uniform(0.3, 0.8))
        xb[k] = np.clip(im, 0, 255).astype(np.uint8)
        yb[k] = m
    return xb, yb


def _iou_counts(logits, masks):
    pred = logits > 0
    tp = int((pred & masks).sum())
    fp = int((pred & ~masks).sum())
    fn = int((~pred & masks).sum())
    return tp, fp, fn


def evaluate(model, imgs, masks, bs=4):
    import torch

    model.eval()
    tp = fp = fn = 0
    with torch.no_grad():
        for s in range(0, len(imgs), bs):
            out = model(_normalise(imgs[s:s + bs]))[:, 0].numpy()
            a, b, c = _iou_counts(out, masks[s:s + bs])
            tp, fp, fn = tp + a, fp + b, fn + c
    model.train()
    return tp / max(tp + fp + fn, 1), 2 * tp / max(2 * tp + fp + fn, 1)


def cmd_train(args):
    import torch
    import torch.nn.functional as F

    torch.set_num_threads(args.threads)
    torch.manual_seed(TRAIN_SEED)
    rng = np.random.default_rng(TRAIN_SEED)
    work = Path(args.work)
    imgs, masks = _load(work, "train")
    vimgs, vmasks = _load(work, "val")
    model = build_model(args.arch)
    if args.init:
        # continue from an earlier run (a second, longer stage of the same recipe)
        model.load_state_dict(torch.load(args.init))
    n_params = sum(p.numel() for p in model.parameters())
    print(f"{args.arch}: {n_params} parameters, {len(imgs)} train / {len(vimgs)} val captures", flush=True)
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    budget = args.minutes * 60
    t0 = time.time()
    last_val = t0
    best = -1.0
    log = []
    it = 0
    while True:
        frac = (time.time() - t0) / budget
        if frac >= 1:
            break
        # warm-up then cosine decay over the wall-clock budget
        lr = args.lr * min(1.0, (it + 1) / 50) * 0.5 * (1 + math.cos(math.pi * frac))
        for g in opt.param_groups:
            g["lr"] = lr
        xb, yb = _batch(imgs, masks, rng, args.crop, args.batch)
        x = _normalise(xb)
        y = torch.from_numpy(yb)[:, None]
        out = model(x)
        p = torch.sigmoid(out)
        dice = 1 - (2 * (p * y).sum() + 1) / (p.sum() + y.sum() + 1)
        loss = F.binary_cross_entropy_with_logits(out, y) + dice
        opt.zero_grad()
        loss.backward()
        opt.step()
        it += 1
        if it % 25 == 0:
            print(f"it {it} t {time.time() - t0:.0f}s lr {lr:.2e} loss {loss.item():.4f}", flush=True)
        if time.time() - last_val > args.val_every_s or (time.time() - t0) >= budget:
            v_iou, v_dice = evaluate(model, vimgs, vmasks)
            last_val = time.time()
            log.append({"it": it, "t_s": round(last_val - t0), "val_iou": v_iou, "val_dice": v_dice})
            print(f"VAL it {it} iou {v_iou:.4f} dice {v_dice:.4f}", flush=True)
            if v_iou > best:
                best = v_iou
                torch.save(model.state_dict(), work / f"{args.tag or args.arch}.pt")
    v_iou, v_dice = evaluate(model, vimgs, vmasks)
    log.append({"it": it, "t_s": round(time.time() - t0), "val_iou": v_iou, "val_dice": v_dice})
    print(f"VAL final it {it} iou {v_iou:.4f} dice {v_dice:.4f}", flush=True)
    if v_iou > best:
        best = v_iou
        torch.save(model.state_dict(), work / f"{args.tag or args.arch}.pt")
    info = {"arch": args.arch, "init": args.init, "parameters": n_params, "iterations": it, "batch": args.batch,
            "crop_px": args.crop, "lr": args.lr, "minutes": args.minutes, "threads": args.threads,
            "train_seed": TRAIN_SEED, "best_val_iou": best, "log": log,
            "train_captures": len(imgs), "val_captures": len(vimgs)}
    (work / f"{args.tag or args.arch}.json").write_text(json.dumps(info, indent=1))


# ---------------------------------------------------------------------------------------------
# export


def cmd_export(args):
    import torch

    work = Path(args.work)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model = build_model(args.arch)
    tag = args.tag or args.arch
    model.load_state_dict(torch.load(work / f"{tag}.pt"))
    model.eval()
    # pick the probability threshold on the validation split (never on the test split)
    vimgs, vmasks = _load(work, "val")
    logits = []
    with torch.no_grad():
        for k in range(0, len(vimgs), 4):
            logits.append(model(_normalise(vimgs[k:k + 4]))[:, 0].numpy())
    logits = np.concatenate(logits)
    best_t, best_iou = 0.0, -1.0
    for t in np.arange(-2.0, 1.01, 0.25):
        tp, fp, fn = _iou_counts(logits - t, vmasks)
        v = tp / max(tp + fp + fn, 1)
        print(f"threshold logit {t:+.2f}: val IoU {v:.4f}")
        if v > best_iou:
            best_t, best_iou = float(t), v
    threshold = round(1 / (1 + math.exp(-best_t)), 4)
    x = torch.zeros(1, 3, IN_H, IN_W)
    onnx_path = out / f"{args.name}.onnx"
    torch.onnx.export(model, (x,), str(onnx_path), input_names=["image"], output_names=["logits"],
                      opset_version=17, dynamo=False)
    info_path = work / f"{tag}.json"
    info = json.loads(info_path.read_text()) if info_path.exists() else \
        {"parameters": sum(p.numel() for p in model.parameters()), "best_val_iou": None}
    sidecar = {
        "format": "rebarlib-segmentation/1",
        "input": {"name": "image", "size": [IN_W, IN_H], "channel_order": "RGB",
                  "mean": MEAN, "std": STD, "layout": "NCHW", "dtype": "float32"},
        "output": {"name": "logits", "kind": "logits", "rebar_classes": [0], "threshold": threshold},
        "model": {"architecture": args.arch, "trained_by": "training/train_segmentation.py",
                  "parameters": info["parameters"], "best_val_iou": None if info["best_val_iou"] is None else round(info["best_val_iou"], 5),
                  "val_iou_at_threshold": round(best_iou, 5)},
    }
    (out / f"{args.name}.json").write_text(json.dumps(sidecar, indent=2) + "\n")
    print("wrote", onnx_path, onnx_path.stat().st_size, "bytes")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("data")
    a.add_argument("--work", default="/tmp/rebar_seg")
    a.add_argument("--n", type=int, default=None)
    a = sub.add_parser("train")
    a.add_argument("--work", default="/tmp/rebar_seg")
    a.add_argument("--arch", choices=["unet", "deeplab"], required=True)
    a.add_argument("--minutes", type=float, default=18)
    a.add_argument("--threads", type=int, default=1)
    a.add_argument("--batch", type=int, default=8)
    a.add_argument("--crop", type=int, default=224)
    a.add_argument("--lr", type=float, default=3e-3)
    a.add_argument("--val-every-s", type=float, default=240)
    a.add_argument("--init", default=None, help="state dict to start from (continue training)")
    a.add_argument("--tag", default=None, help="name of the outputs (default: the arch)")
    a = sub.add_parser("export")
    a.add_argument("--work", default="/tmp/rebar_seg")
    a.add_argument("--arch", choices=["unet", "deeplab"], required=True)
    a.add_argument("--out", default="rebarlib/models")
    a.add_argument("--name", default="rebar_seg")
    a.add_argument("--tag", default=None, help="which trained run (default: the arch)")
    args = ap.parse_args(argv)
    if args.cmd == "data" and args.n is None:
        from rebarlib.segmentation import DATASET_SIZE
        args.n = DATASET_SIZE
    {"data": cmd_data, "train": cmd_train, "export": cmd_export}[args.cmd](args)


if __name__ == "__main__":
    main()
