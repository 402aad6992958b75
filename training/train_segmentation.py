"""Train the shipped rebar segmentation model on synthetic captures, on the CPU, and export it.

Steps (each resumable, outputs under ``--work``):

    python training/train_segmentation.py data   --work /tmp/seg   # render the 6:2:2 data set
    python training/train_segmentation.py train  --work /tmp/seg --arch unet    --minutes 18
    python training/train_segmentation.py train  --work /tmp/seg --arch deeplab --minutes 18
    python training/train_segmentation.py export --work /tmp/seg --arch unet --out rebarlib/models

The data set is ``rebarlib.synth_segmentation.synth_segmentation_capture(i)`` for
``i < DATASET_SIZE``, rendered at 640 x 400 (``GEMINI2.scaled(0.5)``); the split is
``rebarlib.synth_segmentation.split_indices()`` (by capture, seeded). The models see the colour image
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
ARCHS = ["unet", "deeplab", "deeplab_fine", "deeplab_fine_w", "deeplab_fine_w25", "deeplab_fine_w3"]


# ---------------------------------------------------------------------------------------------
# data


def _entry(key) -> tuple[int, bool]:
    """(capture index, ribs in relief) of a data-set entry: ``42`` (smooth bars) or ``"42r"``
    (the same index drawn with its ribs in relief)."""
    relief = isinstance(key, str) and key.endswith("r")
    return int(key[:-1]) if relief else int(key), relief


def _stem(key) -> str:
    """File stem of a data-set entry: 42 -> "0042", "42r" -> "0042r"."""
    index, relief = _entry(key)
    return f"{index:04d}" + ("r" if relief else "")


def _render_one(job):
    import cv2

    from rebarlib.synth_segmentation import DATASET_SEED, synth_segmentation_capture

    key, folder, quality, relief_label, keep_full, full_quality = job
    f_img, f_mask = folder / f"{_stem(key)}.jpg", folder / f"{_stem(key)}.png"
    f_full = folder / f"{_stem(key)}.full.jpg"
    index, relief = _entry(key)
    cap = None
    if (
        not f_img.exists()
        or (relief and relief_label == "silhouette" and not f_mask.exists())
        or (keep_full and not f_full.exists())
    ):
        # rendered at the camera's full 1280 x 800 and area-resized to the model's input exactly
        # as SegmentationModel does at run time (rendered again, identically, where only a
        # relief capture's silhouette label is missing)
        cap = synth_segmentation_capture(index, seed=DATASET_SEED, rib_relief=relief)
        small = cv2.resize(cap.color, (IN_W, IN_H), interpolation=cv2.INTER_AREA)
        tmp_img = f_img.with_suffix(".tmp.jpg")
        cv2.imwrite(str(tmp_img), small[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, quality])
        tmp_img.replace(f_img)
    if keep_full and cap is not None and not f_full.exists():
        # a relief training capture (and, with ``data --full``, every training capture) also
        # keeps its full-resolution render: a rib is 1-3 px high there, under a pixel at the half
        # resolution input, and the tiles of SegmentationModel.predict_proba(tiled=True) show
        # the bars at full resolution, sharper than the half-resolution input enlarged
        # (train --full-zoom takes the enlarged crops of training captures from it)
        tmp_full = f_full.with_suffix(".tmp.jpg")
        cv2.imwrite(str(tmp_full), cap.color[:, :, ::-1], [cv2.IMWRITE_JPEG_QUALITY, full_quality])
        tmp_full.replace(f_full)
    if not f_mask.exists():
        # The label stays at full resolution, so the loss sees the bar edges to the
        # full-resolution pixel (logits upsampled x2, as at run time). A bar with ribs in
        # relief is labelled with its outline over the ribs (the same scene drawn with each
        # bar as its smooth rib envelope), as an annotator outlines a ribbed bar and as the
        # diameter stage reads a mask (bar sizes by their rib envelope): the gaps between the
        # ribs, a few pixels long at most, are not "formwork". With ``relief_label ==
        # "silhouette"`` it is labelled with what the render shows instead: the ribs' crests and
        # the core between them, as the diameter stage reads the true mask of a relief capture
        if cap is None or (relief and relief_label == "outline"):  # (else the render has them)
            cap = synth_segmentation_capture(index, seed=DATASET_SEED)
        lab = cap.labels > 0
        tmp_mask = f_mask.with_suffix(".tmp.png")
        cv2.imwrite(
            str(tmp_mask), lab.astype(np.uint8) * 255, [cv2.IMWRITE_PNG_COMPRESSION, 9, cv2.IMWRITE_PNG_BILEVEL, 1]
        )  # 1 bit per pixel
        tmp_mask.replace(f_mask)
    return key


def _full_renders(split: dict, relief_full: int | None = None, every: bool = False) -> set:
    """The entries whose full-resolution render ``data`` keeps: the relief training captures
    (the first ``relief_full`` of them; all if None), every training capture if ``every``, never
    a validation capture (``train --full-zoom`` reads training crops only)."""
    relief_train = [k for k in split["train"] if _entry(k)[1]]
    return set(relief_train[:relief_full]) | (set(split["train"]) if every else set())


def cmd_data(args):
    """Render the train and validation captures (the test captures are the benchmark's alone).

    Indices ``0..DATASET_SIZE-1`` are split 6:2:2 by ``split_indices``; ``--extra N`` adds indices
    ``DATASET_SIZE..DATASET_SIZE+N-1``, all of them training captures, so the validation and test
    splits stay the same whatever the training set's size.

    Real bars are ribbed: ``--relief N`` adds N more training captures, the next indices after
    the extra ones, rendered with their ribs in relief (``rib_relief=True``; about 10 x the
    render time of a smooth one) and labelled with each bar's outline over its ribs, or with
    ``--relief-label silhouette`` with the ribs as the render shows them (see
    ``_render_one``), and ``--relief-val M`` validates on the first M validation captures
    rendered that way too (entries ``"<index>r"`` in ``split.json``).
    """
    from concurrent.futures import ProcessPoolExecutor

    from rebarlib.synth_segmentation import DATASET_SEED, split_indices

    work = Path(args.work)
    (work / "data").mkdir(parents=True, exist_ok=True)
    split = split_indices(args.n, seed=DATASET_SEED)
    first_relief = args.n + args.extra
    split = {
        "train": [int(i) for i in split["train"]]
        + list(range(args.n, first_relief))
        + [f"{i}r" for i in range(first_relief, first_relief + args.relief)],
        "val": [int(i) for i in split["val"]] + [f"{int(i)}r" for i in split["val"][: args.relief_val]],
        "test": [int(i) for i in split["test"]],
    }
    # smooth captures first (quick), then the relief ones
    wanted = sorted(split["train"] + split["val"], key=lambda k: _entry(k)[::-1])
    t0 = time.time()
    full = _full_renders(split, args.relief_full, args.full)
    jobs = [(i, work / "data", args.jpeg_quality, args.relief_label, i in full, args.full_quality) for i in wanted]
    with ProcessPoolExecutor(args.jobs) as ex:
        for n, _ in enumerate(ex.map(_render_one, jobs, chunksize=4)):
            if n % 20 == 0:
                print(f"{n}/{len(wanted)} {time.time() - t0:.0f} s", flush=True)
    (work / "split.json").write_text(json.dumps(split))
    print("done", round(time.time() - t0), "s")


def _load(work: Path, part: str):
    """(images (N, IN_H, IN_W, 3) uint8 RGB, full-resolution masks (N, 2*IN_H, 2*IN_W) bool)."""
    import cv2

    split = json.loads((work / "split.json").read_text())
    imgs, masks = [], []
    for i in split[part]:
        imgs.append(cv2.imread(str(work / "data" / f"{_stem(i)}.jpg"))[:, :, ::-1])
        masks.append(cv2.imread(str(work / "data" / f"{_stem(i)}.png"), cv2.IMREAD_GRAYSCALE) > 0)
    return np.ascontiguousarray(np.stack(imgs)), np.stack(masks)


def _load_dr(folder: Path, val_every: int):
    """The domain-randomised scenes of ``training/domain_random.py`` in ``folder``: (train
    images, train masks, val images, val masks) as :func:`_load` gives them; every scene whose
    index is a multiple of ``val_every`` validates. Scenes whose two files are not both there
    yet (the data step still running) are skipped."""
    import cv2

    stems = sorted(
        p.stem for p in folder.glob("*.jpg") if not p.stem.endswith(".tmp") and (folder / f"{p.stem}.png").exists()
    )
    imgs = [cv2.imread(str(folder / f"{s}.jpg"))[:, :, ::-1] for s in stems]
    masks = [cv2.imread(str(folder / f"{s}.png"), cv2.IMREAD_GRAYSCALE) > 0 for s in stems]
    imgs, masks = np.ascontiguousarray(np.stack(imgs)), np.stack(masks)
    val = np.array([int(s) % val_every == 0 for s in stems])
    return imgs[~val], masks[~val], imgs[val], masks[val]


class _GrowingDR:
    """The training scenes of a domain-randomised folder that a data step is still writing, on
    the training device: a buffer for ``capacity`` scenes filled as they appear (``grow``
    reads only the scenes not yet loaded, on a few threads). The validation scenes (index a
    multiple of ``val_every``) are those there at the start and stay fixed, so the logged
    validation IoU compares across the run."""

    def __init__(self, folder: Path, val_every: int, capacity: int, dev):
        import torch

        self.folder, self.val_every, self.dev = folder, val_every, dev
        self.known: set[str] = set()
        self.n = 0
        stems, _ = self._new()
        val = [s for s in stems if int(s) % val_every == 0]
        vi, vm = self._read(val)  # every scene has the size of the first (domain_random.py --size)
        self.imgs = torch.empty((capacity,) + vi.shape[1:], dtype=torch.uint8, device=dev)
        self.masks = torch.empty((capacity,) + vm.shape[1:], dtype=torch.bool, device=dev)
        self.val = (torch.from_numpy(vi).to(dev), torch.from_numpy(vm).to(dev))
        self.known.update(val)
        self.grow()

    def _new(self):
        stems = sorted(
            p.stem
            for p in self.folder.glob("*.jpg")
            if not p.stem.endswith(".tmp") and p.stem not in self.known and (self.folder / f"{p.stem}.png").exists()
        )
        return stems, [s for s in stems if int(s) % self.val_every]

    def _read(self, stems):
        from concurrent.futures import ThreadPoolExecutor

        import cv2

        def one(s):
            return (
                cv2.imread(str(self.folder / f"{s}.jpg"))[:, :, ::-1],
                cv2.imread(str(self.folder / f"{s}.png"), cv2.IMREAD_GRAYSCALE) > 0,
            )

        with ThreadPoolExecutor(4) as ex:
            pairs = list(ex.map(one, stems))
        return np.ascontiguousarray(np.stack([a for a, _ in pairs])), np.stack([b for _, b in pairs])

    def grow(self) -> int:
        """Load the training scenes written since the last call (up to the capacity); their count."""
        import torch

        _, train = self._new()
        train = train[: len(self.imgs) - self.n]
        if not train:
            return self.n
        for k in range(0, len(train), 512):
            part = train[k : k + 512]
            im, m = self._read(part)
            self.imgs[self.n : self.n + len(part)] = torch.from_numpy(im).to(self.dev)
            self.masks[self.n : self.n + len(part)] = torch.from_numpy(m).to(self.dev)
            self.n += len(part)
            self.known.update(part)
        return self.n

    def train(self):
        return self.imgs[: self.n], self.masks[: self.n]


def _load_full(work: Path, part: str) -> dict:
    """{position in the part: full-resolution image (2*IN_H, 2*IN_W, 3) uint8 RGB} for the entries
    whose full-resolution render was kept (see ``_full_renders``)."""
    import cv2

    split = json.loads((work / "split.json").read_text())
    full = {}
    for k, i in enumerate(split[part]):
        f = work / "data" / f"{_stem(i)}.full.jpg"
        if f.is_file():
            full[k] = np.ascontiguousarray(cv2.imread(str(f))[:, :, ::-1])
    return full


# ---------------------------------------------------------------------------------------------
# models


def build_model(arch: str):
    import torch
    from torch import nn
    import torch.nn.functional as F

    def cbr(cin, cout, k=3, s=1, d=1):
        return nn.Sequential(
            nn.Conv2d(cin, cout, k, s, padding=d * (k // 2), dilation=d, bias=False),
            nn.BatchNorm2d(cout),
            nn.ReLU(inplace=True),
        )

    def ds(cin, cout, s=1, d=1):
        # depthwise-separable conv (MobileNet-style light backbone)
        return nn.Sequential(
            nn.Conv2d(cin, cin, 3, s, padding=d, dilation=d, groups=cin, bias=False),
            nn.BatchNorm2d(cin),
            nn.ReLU(inplace=True),
            nn.Conv2d(cin, cout, 1, bias=False),
            nn.BatchNorm2d(cout),
            nn.ReLU(inplace=True),
        )

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
        """DeepLabV3+-style: separable backbone to 1/16, ASPP, decoder at 1/4, bilinear to input.

        ``fine=True`` adds a second decoder stage at 1/2 of the input with the stem's features
        as the skip (the bar edges then come from 1/2-resolution features, not 1/4); ``width``
        scales every channel count.
        """

        def __init__(self, fine=False, width=1.0):
            super().__init__()
            c = lambda n: max(8, int(round(n * width / 8)) * 8)  # noqa: E731
            c16, c24, c48, c96, c64 = 16, c(24), c(48), c(96), c(64)
            self.fine = fine
            self.stem = cbr(3, c16, s=2)
            self.l1 = nn.Sequential(ds(c16, c24, s=2), ds(c24, c24))
            self.l2 = nn.Sequential(ds(c24, c48, s=2), ds(c48, c48))
            self.l3 = nn.Sequential(ds(c48, c96, s=2), ds(c96, c96), ds(c96, c96, d=2))
            self.a0 = cbr(c96, c48, k=1)
            self.a1 = ds(c96, c48, d=2)
            self.a2 = ds(c96, c48, d=4)
            self.a3 = ds(c96, c48, d=8)
            self.pool = nn.Sequential(nn.AdaptiveAvgPool2d(1), nn.Conv2d(c96, c48, 1), nn.ReLU(inplace=True))
            self.proj = cbr(5 * c48, c64, k=1)
            self.low = cbr(c24, 16, k=1)
            self.dec = nn.Sequential(ds(c64 + 16, c48), ds(c48, c48))
            if fine:
                self.low2 = cbr(c16, 8, k=1)
                self.dec2 = nn.Sequential(ds(c48 + 8, 24), ds(24, 24))
                self.head = nn.Conv2d(24, 1, 1)
            else:
                self.head = nn.Conv2d(c48, 1, 1)

        def forward(self, x):
            s = self.stem(x)
            low = self.l1(s)
            f = self.l3(self.l2(low))
            g = self.pool(f).expand(-1, -1, f.shape[2], f.shape[3])
            a = self.proj(torch.cat([self.a0(f), self.a1(f), self.a2(f), self.a3(f), g], 1))
            y = self.dec(torch.cat([up(a, low), self.low(low)], 1))
            if self.fine:
                y = self.dec2(torch.cat([up(y, s), self.low2(s)], 1))
            return up(self.head(y), x)

    archs = {
        "unet": UNetSmall,
        "deeplab": DeepLabLite,
        "deeplab_fine": lambda: DeepLabLite(fine=True),
        "deeplab_fine_w": lambda: DeepLabLite(fine=True, width=1.5),
        # stage 14: wider still, for a single run without the test-time flips in the same time
        "deeplab_fine_w25": lambda: DeepLabLite(fine=True, width=2.5),
        "deeplab_fine_w3": lambda: DeepLabLite(fine=True, width=3.0),
    }
    return archs[arch]()


# ---------------------------------------------------------------------------------------------
# training


def _normalise(x_u8):
    """(N, H, W, 3) uint8 RGB tensor (any device) -> normalised float NCHW."""
    return _standardise(x_u8.float().permute(0, 3, 1, 2))


def _standardise(x):
    """(N, 3, H, W) float RGB in 0-255 -> (x - mean) / std, the model's input."""
    import torch

    mean = torch.tensor(MEAN, device=x.device).view(1, 3, 1, 1)
    std = torch.tensor(STD, device=x.device).view(1, 3, 1, 1)
    return (x - mean) / std


def _upsample2(logits):
    """Input-resolution logits -> full (x2) resolution, bilinear, as SegmentationModel does."""
    import torch.nn.functional as F

    return F.interpolate(logits, scale_factor=2, mode="bilinear", align_corners=False)


def _shadow(x, g):
    """Cast-shadow augmentation: darken the part of each image behind a random soft-edged
    line or band (penumbra 1-8 px) to 25-70 % and tint it towards sky light, so that bars in
    shadow are seen with every formwork, colour and light the renderer makes.
    x: (B, 3, H, W) float 0-255 on any device; g: torch.Generator on x's device."""
    import torch

    B, _, H, W = x.shape
    dev = x.device
    r = lambda *shape: torch.rand(*shape, generator=g, device=dev)  # noqa: E731
    yy, xx = torch.meshgrid(
        torch.arange(H, device=dev, dtype=torch.float32),
        torch.arange(W, device=dev, dtype=torch.float32),
        indexing="ij",
    )
    th = r(B) * 2 * math.pi
    cx, cy = r(B) * W, r(B) * H
    d = (xx[None] - cx[:, None, None]) * torch.cos(th)[:, None, None] + (yy[None] - cy[:, None, None]) * torch.sin(th)[
        :, None, None
    ]
    band = r(B) < 0.5  # a band (a shadow of a bar or a board) rather than a half-plane
    half_w = 4 + r(B) * 60
    d = torch.where(band[:, None, None], half_w[:, None, None] - d.abs(), d)
    soft = 1 + r(B) * 7
    inside = torch.sigmoid(d / soft[:, None, None])[:, None]
    dark = 0.25 + 0.45 * r(B)
    tint = torch.stack([0.92 + 0.05 * r(B), 0.96 + 0.03 * r(B), torch.ones(B, device=dev)], 1)
    factor = 1 - inside * (1 - dark[:, None, None, None] * tint[:, :, None, None])
    use = (r(B) < 0.5).float()[:, None, None, None]
    return x * (1 - use + use * factor)


def _colour_jitter(x, g):
    """Colours the renderer does not draw, so that the network leans on shape and shading more
    than on the renderer's palette (real formwork and bars come in colours it never drew):
    saturation 0.4-1.6 (grey on a tenth of the crops), contrast 0.6-1.4 about the crop's mean,
    and on a fifth of the crops the colour channels in another order (one order per batch).
    x: (B, 3, H, W) float 0-255 on any device; g: torch.Generator on x's device."""
    import torch

    B, dev = x.shape[0], x.device
    r = lambda *shape: torch.rand(*shape, generator=g, device=dev)  # noqa: E731
    grey = (x * torch.tensor([0.299, 0.587, 0.114], device=dev).view(1, 3, 1, 1)).sum(1, keepdim=True)
    sat = 0.4 + 1.2 * r(B, 1, 1, 1)
    sat = torch.where(r(B, 1, 1, 1) < 0.1, torch.zeros_like(sat), sat)
    x = grey + sat * (x - grey)
    mean = x.mean((1, 2, 3), keepdim=True)
    x = mean + (0.6 + 0.8 * r(B, 1, 1, 1)) * (x - mean)
    swap = r(B) < 0.2
    order = torch.argsort(r(3))
    x = torch.where(swap[:, None, None, None], x[:, order], x)
    return x.clamp(0, 255)


def _batch(imgs, masks, g, size, bs, zoom=0.0, full=None, colour=False):
    """A training batch on the data's device: random crops (input size x size, label 2size x
    2size), flips, transposition, gain / gamma / blur / noise jitter and cast shadows.

    ``zoom``: the share of crops taken smaller (size / z, z uniform in 1..2) and enlarged to
    size x size (the label likewise, bilinearly, as a soft label): bars up to twice as wide as
    the data set draws them at the input, as the full-resolution tiles of
    ``SegmentationModel.predict_proba(tiled=True)`` show them. ``full``: {image index: its
    full-resolution render (torch uint8, on the device)}; an enlarged crop of such an image is
    taken from it (2c x 2c pixels area-resized to size x size) instead of enlarging the
    half-resolution input, so the network sees the detail the tiles show (a rib 1-3 px high).
    ``colour``: also draw colours the renderer does not (see :func:`_colour_jitter`)."""
    import torch
    import torch.nn.functional as F

    dev = imgs.device
    n, H, W = imgs.shape[:3]
    r = lambda *shape: torch.rand(*shape, generator=g, device=dev)  # noqa: E731
    z = torch.where(r(bs) < zoom, 1 + r(bs), torch.ones(bs, device=dev)).tolist()
    cs = [min(size, max(8, round(size / zk))) for zk in z]
    idx = (r(bs) * n).long().tolist()
    fy, fx = r(bs).tolist(), r(bs).tolist()
    flips = (r(bs, 3) < 0.5).tolist()
    xs, ys = [], []
    for k in range(bs):
        c = cs[k]
        y0, x0 = int(fy[k] * (H - c + 1)), int(fx[k] * (W - c + 1))
        if c != size and full is not None and idx[k] in full:
            im = full[idx[k]][2 * y0 : 2 * (y0 + c), 2 * x0 : 2 * (x0 + c)]
        else:
            im = imgs[idx[k], y0 : y0 + c, x0 : x0 + c]
        m = masks[idx[k], 2 * y0 : 2 * (y0 + c), 2 * x0 : 2 * (x0 + c)]
        if flips[k][0]:
            im, m = im.flip(1), m.flip(1)
        if flips[k][1]:
            im, m = im.flip(0), m.flip(0)
        if flips[k][2]:
            im, m = im.transpose(0, 1), m.transpose(0, 1)
        im, m = im.permute(2, 0, 1).float(), m[None].float()
        if c != size:
            mode = dict(mode="area") if im.shape[-1] > size else dict(mode="bilinear", align_corners=False)
            im = F.interpolate(im[None], size=(size, size), **mode)[0]
            m = F.interpolate(m[None], size=(2 * size, 2 * size), mode="bilinear", align_corners=False)[0]
        xs.append(im)
        ys.append(m)
    x = torch.stack(xs)
    y = torch.stack(ys)
    x = _shadow(x, g)
    if colour:
        x = _colour_jitter(x, g)
    # photometric jitter beyond the renderer's own: gain per channel and overall, gamma
    x = x * (0.85 + 0.3 * r(bs, 3, 1, 1)) * (0.8 + 0.4 * r(bs, 1, 1, 1))
    x = 255 * (x.clamp(0, 255) / 255) ** (0.8 + 0.45 * r(bs, 1, 1, 1))
    # slight blur on some images (a 5-tap Gaussian of random sigma), sensor noise on some
    sig = 0.3 + 0.5 * r(bs)
    t = torch.arange(-2, 3, device=dev, dtype=torch.float32)
    k1 = torch.exp(-(t[None] ** 2) / (2 * sig[:, None] ** 2))
    k1 = k1 / k1.sum(1, keepdim=True)
    blur = r(bs) < 0.3
    if blur.any():
        xb = x[blur]
        kb = k1[blur]
        B = xb.shape[0]
        xb = xb.reshape(1, B * 3, size, size)
        kh = kb.repeat_interleave(3, 0)[:, None, None, :]
        kv = kb.repeat_interleave(3, 0)[:, None, :, None]
        xb = F.conv2d(F.pad(xb, (2, 2, 0, 0), mode="replicate"), kh, groups=B * 3)
        xb = F.conv2d(F.pad(xb, (0, 0, 2, 2), mode="replicate"), kv, groups=B * 3)
        x[blur] = xb.reshape(B, 3, size, size)
    noisy = (r(bs) < 0.3).float()[:, None, None, None]
    x = x + noisy * torch.randn(x.shape, generator=g, device=dev) * (6 * r(bs, 1, 1, 1))
    return _standardise(x.clamp(0, 255).round()), y


def _iou_counts(logits, masks):
    pred = logits > 0
    tp = int((pred & masks).sum())
    fp = int((pred & ~masks).sum())
    fn = int((~pred & masks).sum())
    return tp, fp, fn


def _logits_full(model, imgs, bs=4, flips=()):
    """Full-resolution logits of whole images (float32, on the images' device); with ``flips``
    (any of "h", "v", "hv") averaged with the mirrored images' logits, mirrored back, as
    SegmentationModel does for a sidecar with ``input.flips``."""
    import torch

    out = []
    with torch.no_grad():
        for s in range(0, len(imgs), bs):
            x = _normalise(imgs[s : s + bs])
            y = model(x).float()
            for f in flips:
                dims = [d for d, c in ((2, "v"), (3, "h")) if c in f]
                y = y + model(x.flip(dims)).float().flip(dims)
            out.append(_upsample2(y / (1 + len(flips)))[:, 0])
    return torch.cat(out)


def evaluate(model, imgs, masks, bs=4, flips=()):
    """Validation IoU and Dice at full resolution (logits upsampled x2, threshold p = 0.5; with
    ``flips`` averaged as in :func:`_logits_full`). Every module's training mode is left as it
    was (frozen batch norms stay frozen)."""
    modes = [(mod, mod.training) for mod in model.modules()]
    model.eval()
    tp = fp = fn = 0
    for s in range(0, len(imgs), bs):
        a, b, c = _iou_counts(_logits_full(model, imgs[s : s + bs], flips=flips), masks[s : s + bs])
        tp, fp, fn = tp + a, fp + b, fn + c
    for mod, was in modes:
        mod.train(was)
    return tp / max(tp + fp + fn, 1), 2 * tp / max(2 * tp + fp + fn, 1)


def state_from_onnx(model, onnx_path):
    """A state dict for ``model`` (one of :func:`build_model`'s networks, in eval mode) from an
    ONNX file this script exported from the same architecture, so that training can go on from
    a shipped model whose checkpoint is not kept.

    The exporter folds every batch norm into the convolution before it: each Conv node (named
    after its module, ``/l1/l1.0/l1.0.0/Conv``) carries W·γ/σ and β − μγ/σ. Those go into the
    convolution and the batch norm after it becomes the identity with that bias (γ = 1,
    running mean 0, running variance 1 − eps). The network then computes exactly what the ONNX
    model does in eval mode; train it with its batch norms frozen (``--freeze-bn``), since batch
    statistics would undo the folded scales."""
    import onnx
    import torch
    from onnx import numpy_helper

    graph = onnx.load(str(onnx_path)).graph
    inits = {i.name: numpy_helper.to_array(i) for i in graph.initializer}
    own = model.state_dict()
    state = {k: v.clone() for k, v in own.items()}
    done = set()
    for node in graph.node:
        if node.op_type != "Conv":
            continue
        path = node.name.split("/")[-2]  # the conv's module: "l1.0.0", "head", ...
        w, b = inits[node.input[1]], inits[node.input[2]]
        if f"{path}.weight" not in own or tuple(own[f"{path}.weight"].shape) != w.shape:
            raise ValueError(f"{onnx_path}: Conv {node.name} matches no convolution of this architecture")
        state[f"{path}.weight"] = torch.from_numpy(w.copy())
        head, _, last = path.rpartition(".")
        bn = f"{head}.{int(last) + 1}" if last.isdigit() else None
        if f"{path}.bias" in own:
            state[f"{path}.bias"] = torch.from_numpy(b.copy())
        elif bn is not None and f"{bn}.running_var" in own:
            eps = 1e-5
            state[f"{bn}.weight"] = torch.ones_like(own[f"{bn}.weight"])
            state[f"{bn}.bias"] = torch.from_numpy(b.copy())
            state[f"{bn}.running_mean"] = torch.zeros_like(own[f"{bn}.running_mean"])
            state[f"{bn}.running_var"] = torch.full_like(own[f"{bn}.running_var"], 1 - eps)
            done.add(bn)
        else:
            raise ValueError(f"{onnx_path}: Conv {node.name} has a bias but its module has neither bias nor batch norm")
        done.add(path)
    missing = sorted({k.rsplit(".", 1)[0] for k in own} - done)
    if missing:
        raise ValueError(f"{onnx_path}: no weights for {', '.join(missing)}")
    return state


def _train_mode(model, freeze_bn: bool):
    """Training mode, with the batch norms in eval mode (running statistics, kept) if ``freeze_bn``."""
    from torch import nn

    model.train()
    if freeze_bn:
        for mod in model.modules():
            if isinstance(mod, nn.BatchNorm2d):
                mod.eval()


def cmd_train(args):
    import torch
    import torch.nn.functional as F

    dev = torch.device(args.device if args.device != "auto" else ("cuda" if torch.cuda.is_available() else "cpu"))
    if dev.type == "cpu":
        torch.set_num_threads(args.threads)
    torch.manual_seed(TRAIN_SEED)
    g = torch.Generator(device=dev)
    g.manual_seed(TRAIN_SEED)
    work = Path(args.work)
    out_dir = Path(args.out_dir or work)
    out_dir.mkdir(parents=True, exist_ok=True)
    tag = args.tag or args.arch
    imgs, masks = (torch.from_numpy(a).to(dev) for a in _load(work, "train"))
    vimgs, vmasks = (torch.from_numpy(a).to(dev) for a in _load(work, "val"))
    dr = growing = None
    if args.dr_work and args.dr_capacity:
        # scenes that a data step beside the training is writing: loaded as they appear
        growing = _GrowingDR(Path(args.dr_work) / "dr", args.dr_val, args.dr_capacity, dev)
        dr = [*growing.train(), *growing.val]
        print(
            f"--dr-capacity: {len(dr[0])} train / {len(dr[2])} val domain-randomised scenes at the start, "
            f"{args.dr_share:.0%} of each batch",
            flush=True,
        )
    elif args.dr_work:
        dr = [torch.from_numpy(a).to(dev) for a in _load_dr(Path(args.dr_work) / "dr", args.dr_val)]
        print(
            f"--dr-work: {len(dr[0])} train / {len(dr[2])} val domain-randomised scenes, "
            f"{args.dr_share:.0%} of each batch",
            flush=True,
        )
    full = None
    if args.full_zoom:
        full = {k: torch.from_numpy(a).to(dev) for k, a in _load_full(work, "train").items()}
        print(
            f"--full-zoom: {len(full)} training captures' enlarged crops from their full-resolution render", flush=True
        )
    model = build_model(args.arch).to(dev)
    if args.init:
        # continue from an earlier run (a second, longer stage of the same recipe), or start a
        # larger architecture from a smaller one's weights: every tensor whose name and shape
        # match is copied, the rest keep their fresh initialisation and are listed
        own = model.state_dict()
        given = torch.load(args.init, map_location=dev)
        same = {k: v for k, v in given.items() if k in own and own[k].shape == v.shape}
        model.load_state_dict(same, strict=False)
        fresh = sorted({k.split(".")[0] for k in own if k not in same})
        if fresh:
            print(
                f"init from {args.init}: {len(same)} of {len(own)} tensors copied; "
                f"freshly initialised: {', '.join(fresh)}",
                flush=True,
            )
    if args.init_onnx:
        model.load_state_dict(state_from_onnx(model, args.init_onnx))
        print(f"init from {args.init_onnx} (batch norms folded into the convolutions)", flush=True)
    if dev.type == "cuda":  # channels-last convolutions, cuDNN's fastest algorithms for the crop size
        model = model.to(memory_format=torch.channels_last)
        torch.backends.cudnn.benchmark = True
    _train_mode(model, args.freeze_bn)
    n_params = sum(p.numel() for p in model.parameters())
    print(
        f"{tag}: {args.arch}, {n_params} parameters, {len(imgs)} train / {len(vimgs)} val captures, device {dev}",
        flush=True,
    )
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    amp = (
        dict(device_type="cuda", dtype=torch.bfloat16) if dev.type == "cuda" else dict(device_type="cpu", enabled=False)
    )
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
        lr = args.lr * min(1.0, (it + 1) / 100) * 0.5 * (1 + math.cos(math.pi * frac))
        for grp in opt.param_groups:
            grp["lr"] = lr
        n_dr = int(round(args.batch * args.dr_share)) if dr is not None else 0
        x, y = _batch(imgs, masks, g, args.crop, args.batch - n_dr, zoom=args.zoom, full=full, colour=args.colour)
        if n_dr:
            xd, yd = _batch(dr[0], dr[1], g, args.crop, n_dr, zoom=args.zoom, colour=args.colour)
            x, y = torch.cat([x, xd]), torch.cat([y, yd])
        if dev.type == "cuda":
            x = x.contiguous(memory_format=torch.channels_last)
        with torch.autocast(**amp):
            out = _upsample2(model(x)).float()
        p = torch.sigmoid(out)
        dice = 1 - (2 * (p * y).sum() + 1) / (p.sum() + y.sum() + 1)
        loss = F.binary_cross_entropy_with_logits(out, y) + dice
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        it += 1
        if it % 200 == 0:
            print(f"it {it} t {time.time() - t0:.0f}s lr {lr:.2e} loss {loss.item():.4f}", flush=True)
        if time.time() - last_val > args.val_every_s:
            v_iou, v_dice = evaluate(model, vimgs, vmasks)
            entry = {"it": it, "t_s": round(time.time() - t0), "val_iou": v_iou, "val_dice": v_dice}
            if dr is not None:
                entry["dr_val_iou"] = evaluate(model, dr[2], dr[3])[0]
                # every validation keeps a snapshot: the real-photo benchmark picks among them
                torch.save(model.state_dict(), out_dir / f"{tag}_it{it}.pt")
                if growing is not None:  # scenes the data step wrote meanwhile
                    growing.grow()
                    dr[:2] = growing.train()
                    entry["dr_train"] = len(dr[0])
                elif args.dr_work and args.dr_reload:
                    dr = [torch.from_numpy(a).to(dev) for a in _load_dr(Path(args.dr_work) / "dr", args.dr_val)]
                    entry["dr_train"] = len(dr[0])
            last_val = time.time()
            log.append(entry)
            print(
                "VAL " + " ".join(f"{k} {v:.4f}" if isinstance(v, float) else f"{k} {v}" for k, v in entry.items()),
                flush=True,
            )
            if v_iou > best:
                best = v_iou
                torch.save(model.state_dict(), out_dir / f"{tag}.pt")
    v_iou, v_dice = evaluate(model, vimgs, vmasks)
    log.append({"it": it, "t_s": round(time.time() - t0), "val_iou": v_iou, "val_dice": v_dice})
    print(f"VAL final it {it} iou {v_iou:.4f} dice {v_dice:.4f}", flush=True)
    if dr is not None:  # the last state is a snapshot too
        log[-1]["dr_val_iou"] = evaluate(model, dr[2], dr[3])[0]
        torch.save(model.state_dict(), out_dir / f"{tag}_it{it}.pt")
        (out_dir / f"{tag}_last.txt").write_text(f"{tag}_it{it}\n")
    if v_iou > best:
        best = v_iou
        torch.save(model.state_dict(), out_dir / f"{tag}.pt")
    info = {
        "arch": args.arch,
        "init": args.init,
        "parameters": n_params,
        "iterations": it,
        "batch": args.batch,
        "crop_px": args.crop,
        "zoom": args.zoom,
        "full_zoom": args.full_zoom,
        "colour": args.colour,
        "init_onnx": args.init_onnx,
        "freeze_bn": args.freeze_bn,
        "lr": args.lr,
        "minutes": args.minutes,
        "device": str(dev),
        "device_name": torch.cuda.get_device_name(dev) if dev.type == "cuda" else "cpu",
        "threads": args.threads if dev.type == "cpu" else None,
        "torch": torch.__version__,
        "train_seed": TRAIN_SEED,
        "best_val_iou": best,
        "log": log,
        "train_captures": len(imgs),
        "val_captures": len(vimgs),
        "dr_work": args.dr_work,
        "dr_share": args.dr_share if dr is not None else None,
        "dr_train_scenes": len(dr[0]) if dr is not None else None,
    }
    (out_dir / f"{tag}.json").write_text(json.dumps(info, indent=1))


def cmd_eval(args):
    """Validation IoU (%) of trained models, the smooth and the relief validation captures apart,
    without and with the test-time flips h, v and hv: each model an ONNX file exported by this
    script (``state_from_onnx``) or a run's state dict (``.pt``)."""
    import torch

    torch.set_num_threads(args.threads)
    work = Path(args.work)
    split = json.loads((work / "split.json").read_text())
    imgs, masks = _load(work, "val")
    relief = np.array([_entry(k)[1] for k in split["val"]])
    parts = [(name, sel) for name, sel in (("smooth", ~relief), ("relief", relief)) if sel.any()]
    for path in args.models:
        model = build_model(args.arch)
        model.load_state_dict(
            state_from_onnx(model, path) if str(path).endswith(".onnx") else torch.load(path, map_location="cpu")
        )
        row = []
        for flips in ((), ("h", "v", "hv")):
            for name, sel in parts:
                iou, _ = evaluate(model, torch.from_numpy(imgs[sel]), torch.from_numpy(masks[sel]), flips=flips)
                row.append(f"{name}{', flips' if flips else ''} {100 * iou:.2f}")
        print(f"{path}: " + "; ".join(row), flush=True)


# ---------------------------------------------------------------------------------------------
# export


def cmd_export(args):
    import torch

    work = Path(args.work)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    model = build_model(args.arch)
    tag = args.tag or args.arch
    run_dir = Path(args.run_dir or work)
    model.load_state_dict(torch.load(run_dir / f"{tag}.pt", map_location="cpu"))
    model.eval()
    # pick the probability threshold on the validation split (never on the test split), at
    # full resolution as SegmentationModel thresholds it (--device cuda: the logits computed
    # there in float32, TF32 off, then the model exported from the CPU)
    dev = torch.device(args.device)
    torch.backends.cudnn.allow_tf32 = False
    vimgs, vmasks = _load(work, "val")
    vimgs = torch.from_numpy(vimgs).to(dev)
    logits = _logits_full(model.to(dev), vimgs, flips=args.flips).cpu().numpy()
    model = model.cpu()
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
    # --dynamic: any input size (the sidecar then scales a photo by input.scale, keeping its
    # aspect ratio, and pads it to a multiple of input.pad_to instead of squashing it)
    dynamic = {"image": {2: "height", 3: "width"}, "logits": {2: "height", 3: "width"}} if args.dynamic else None
    torch.onnx.export(
        model,
        (x,),
        str(onnx_path),
        input_names=["image"],
        output_names=["logits"],
        opset_version=17,
        dynamo=False,
        dynamic_axes=dynamic,
    )
    info_path = run_dir / f"{tag}.json"
    info = (
        json.loads(info_path.read_text())
        if info_path.exists()
        else {"parameters": sum(p.numel() for p in model.parameters()), "best_val_iou": None}
    )
    sidecar = {
        "format": "rebarlib-segmentation/1",
        "input": {
            "name": "image",
            **({"scale": 0.5, "pad_to": 16} if args.dynamic else {"size": [IN_W, IN_H]}),
            "channel_order": "RGB",
            "mean": MEAN,
            "std": STD,
            "layout": "NCHW",
            "dtype": "float32",
            "flips": list(args.flips),
            **({"max_bar_px": args.max_bar_px} if args.max_bar_px else {}),
        },
        "output": {"name": "logits", "kind": "logits", "rebar_classes": [0], "threshold": threshold},
        "model": {
            "architecture": args.arch,
            "trained_by": "training/train_segmentation.py",
            "parameters": info["parameters"],
            "best_val_iou": None if info["best_val_iou"] is None else round(info["best_val_iou"], 5),
            "val_iou_at_threshold": round(best_iou, 5),
        },
    }
    (out / f"{args.name}.json").write_text(json.dumps(sidecar, indent=2) + "\n")
    print("wrote", onnx_path, onnx_path.stat().st_size, "bytes")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("data")
    a.add_argument("--work", default="/tmp/rebar_seg")
    a.add_argument("--n", type=int, default=None)
    a.add_argument("--extra", type=int, default=0, help="extra training captures beyond the 6:2:2 set")
    a.add_argument("--relief", type=int, default=0, help="extra training captures with ribs in relief")
    a.add_argument("--relief-val", type=int, default=0, help="validation captures also rendered with ribs in relief")
    a.add_argument(
        "--relief-label",
        choices=["outline", "silhouette"],
        default="outline",
        help="label of a relief capture: each bar's outline over its ribs, or its rendered silhouette",
    )
    a.add_argument("--jobs", type=int, default=2)
    a.add_argument("--jpeg-quality", type=int, default=90)
    a.add_argument(
        "--relief-full",
        type=int,
        default=None,
        help="keep the full-resolution render of the first N relief training captures only (default: all)",
    )
    a.add_argument("--full", action="store_true", help="keep every training capture's full-resolution render")
    a.add_argument("--full-quality", type=int, default=95, help="JPEG quality of the full-resolution renders")
    a = sub.add_parser("train")
    a.add_argument("--work", default="/tmp/rebar_seg")
    a.add_argument("--arch", choices=ARCHS, required=True)
    a.add_argument("--minutes", type=float, default=18)
    a.add_argument("--threads", type=int, default=1)
    a.add_argument("--batch", type=int, default=8)
    a.add_argument("--crop", type=int, default=224)
    a.add_argument("--lr", type=float, default=3e-3)
    a.add_argument("--val-every-s", type=float, default=240)
    a.add_argument("--init", default=None, help="state dict to start from (continue training)")
    a.add_argument(
        "--init-onnx", default=None, help="ONNX model exported by this script to start from (see state_from_onnx)"
    )
    a.add_argument("--freeze-bn", action="store_true", help="keep the batch norms' statistics (fine-tuning)")
    a.add_argument("--zoom", type=float, default=0.0, help="share of crops enlarged 1-2 x (bars as tiles show them)")
    a.add_argument(
        "--colour",
        action="store_true",
        help="colour jitter beyond the renderer's palette (saturation, contrast, channel order)",
    )
    a.add_argument(
        "--full-zoom",
        action="store_true",
        help="take the enlarged crops from the full-resolution render where the data keeps one",
    )
    a.add_argument(
        "--dr-work", default=None, help="folder of domain-randomised scenes (training/domain_random.py --work)"
    )
    a.add_argument("--dr-share", type=float, default=0.5, help="share of each batch from --dr-work")
    a.add_argument(
        "--dr-val", type=int, default=20, help="scenes of --dr-work whose index is a multiple of this validate"
    )
    a.add_argument(
        "--dr-reload", action="store_true", help="at every validation, load the scenes the data step wrote meanwhile"
    )
    a.add_argument(
        "--dr-capacity",
        type=int,
        default=0,
        help="load the scenes of --dr-work as a data step beside the training writes them, up to this many "
        "(a buffer on the device; the scenes of the start validate)",
    )
    a.add_argument("--device", default="auto", help="auto (cuda when there is one), cpu or cuda")
    a.add_argument("--out-dir", default=None, help="where the state dict and log go (default: --work)")
    a.add_argument("--tag", default=None, help="name of the outputs (default: the arch)")
    a = sub.add_parser("export")
    a.add_argument("--work", default="/tmp/rebar_seg")
    a.add_argument("--arch", choices=ARCHS, required=True)
    a.add_argument("--out", default="rebarlib/models")
    a.add_argument("--name", default="rebar_seg")
    a.add_argument("--tag", default=None, help="which trained run (default: the arch)")
    a.add_argument("--run-dir", default=None, help="where the run's state dict and log are (default: --work)")
    a.add_argument(
        "--flips",
        nargs="*",
        default=[],
        choices=["h", "v", "hv"],
        help="test-time flips written into the sidecar (the threshold is chosen with them)",
    )
    a.add_argument(
        "--dynamic", action="store_true", help="any input size: the photo scaled by 0.5 and padded, never squashed"
    )
    a.add_argument("--device", default="cpu", help="where the threshold's validation logits are computed")
    a.add_argument(
        "--max-bar-px",
        type=float,
        default=None,
        help="the widest bar (input px) the model was trained on, written into the sidecar",
    )
    a = sub.add_parser("eval")
    a.add_argument("--work", default="/tmp/rebar_seg")
    a.add_argument("--arch", choices=ARCHS, default="deeplab_fine")
    a.add_argument("--threads", type=int, default=2)
    a.add_argument("models", nargs="+", help="ONNX files exported by this script, or runs' state dicts (.pt)")
    args = ap.parse_args(argv)
    if args.cmd == "data" and args.n is None:
        from rebarlib.synth_segmentation import DATASET_SIZE

        args.n = DATASET_SIZE
    {"data": cmd_data, "train": cmd_train, "eval": cmd_eval, "export": cmd_export}[args.cmd](args)


if __name__ == "__main__":
    main()
