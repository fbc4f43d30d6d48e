"""Filling the unknown pixels of an image from the known ones: smooth pull-push
interpolation (Gortler et al. 1996) and texture copied from a shifted part, blended at
its border.  Plain arrays in and out; which pixels are known is the caller's choice.
"""

from __future__ import annotations

import numpy as np


def pull_push(image: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Fill every pixel from the ``known`` ones by pull-push (Gortler et al. 1996).

    Pull: average colour and coverage down an image pyramid; push: at each finer level a
    pixel keeps its own average where its coverage is full and blends in the coarser
    estimate where it is not.  Smooth, and exact on the known pixels.

    Parameters
    ----------
    image : (H, W, 3) float
    known : (H, W) bool

    Returns
    -------
    (H, W, 3) float
    """
    import cv2

    w = known.astype(np.float32)
    num = image.astype(np.float32) * w[..., None]
    levels = [(num, w)]
    while min(levels[-1][1].shape) > 2:
        n, ww = levels[-1]
        levels.append((cv2.pyrDown(n), cv2.pyrDown(ww)))
    n, ww = levels[-1]
    est = np.where(ww[..., None] > 1e-6, n / np.maximum(ww, 1e-6)[..., None],
                   n.reshape(-1, 3).sum(0) / max(float(ww.sum()), 1e-6))
    for n, ww in reversed(levels[:-1]):
        up = cv2.pyrUp(est.astype(np.float32), dstsize=(ww.shape[1], ww.shape[0]))
        a = np.clip(ww, 0.0, 1.0)[..., None]
        est = np.where(a > 1e-6, n / np.maximum(ww, 1e-6)[..., None], 0.0) * a + up * (1 - a)
    return np.where(known[..., None], image, est)


def shift_fill(out: np.ndarray, image: np.ndarray, src: np.ndarray, tgt: np.ndarray,
               min_cover: float = 0.97, min_pixels: int = 30) -> None:
    """Give each connected part of ``tgt`` the texture of a copy of itself shifted onto
    ``src`` pixels, blended at its border (in place on ``out``).

    Per part the shift is the one with least ``|dx| + 2 |dy|`` (rows change scale under
    perspective, columns less) whose shifted part lands on ``src`` for at least
    ``min_cover`` of its pixels; the coverage of every shift comes from one FFT
    correlation.  The copy is corrected by the membrane (pull-push) interpolation of
    the colour differences along the part's border, so it meets its surroundings
    without a seam (a Poisson-like blend).  Parts with no such shift, or smaller than
    ``min_pixels``, keep what ``out`` holds (the smooth fill).

    Parameters
    ----------
    out : (H, W, 3) float, modified in place
    image : (H, W, 3) float, the colours to copy (valid on ``src``)
    src, tgt : (H, W) bool
    """
    import cv2
    from scipy.signal import fftconvolve

    H, W = src.shape
    n, comp = cv2.connectedComponents(tgt.astype(np.uint8), connectivity=8)
    srcf = src.astype(np.float64)
    for c in range(1, n):
        part = comp == c
        ys, xs = np.nonzero(part)
        if len(ys) < min_pixels:
            continue
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
        if y1 - y0 >= H or x1 - x0 >= W:
            continue
        t = part[y0:y1, x0:x1].astype(np.float64)
        cover = fftconvolve(srcf, t[::-1, ::-1], mode="valid") / len(ys)  # (H-h+1, W-w+1)
        p, q = np.nonzero(cover >= min_cover)
        if len(p) == 0:
            continue
        dy, dx = p - y0, q - x0
        best = np.argmin(np.abs(dx) + 2 * np.abs(dy))
        dy, dx = int(dy[best]), int(dx[best])
        ok = src[ys + dy, xs + dx]
        copy = image[ys + dy, xs + dx]
        # border: the known pixels around the part, and what the copy would put there
        ring = cv2.dilate(part.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) \
            & ~tgt & src
        ry, rx = np.nonzero(ring)
        inside = (ry + dy >= 0) & (ry + dy < H) & (rx + dx >= 0) & (rx + dx < W)
        ry, rx = ry[inside], rx[inside]
        pad = 4
        by0, by1 = max(y0 - pad, 0), min(y1 + pad, H)
        bx0, bx1 = max(x0 - pad, 0), min(x1 + pad, W)
        resid = np.zeros((by1 - by0, bx1 - bx0, 3), np.float32)
        known = np.zeros(resid.shape[:2], bool)
        resid[ry - by0, rx - bx0] = image[ry, rx] - image[ry + dy, rx + dx]
        known[ry - by0, rx - bx0] = True
        if known.any():
            corr = pull_push(resid, known)[ys - by0, xs - bx0]
        else:
            corr = 0.0
        out[ys[ok], xs[ok]] = (copy + corr)[ok]


__all__ = ["pull_push", "shift_fill"]
