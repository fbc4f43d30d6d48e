"""Comparing two images: PSNR, SSIM (Wang et al. 2004), and a labelled side-by-side
picture."""

from __future__ import annotations

import numpy as np


def psnr(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Peak signal-to-noise ratio (dB, peak 255) of two uint8 images over ``mask`` pixels
    (all when None); inf when they are equal there, NaN when the mask is empty."""
    diff = a.astype(float) - b.astype(float)
    if mask is not None:
        diff = diff[mask]
    if diff.size == 0:
        return float("nan")
    mse = float(np.mean(diff ** 2))
    return float("inf") if mse == 0 else float(10 * np.log10(255.0 ** 2 / mse))


def ssim_map(a: np.ndarray, b: np.ndarray, sigma: float = 1.5) -> np.ndarray:
    """Per-pixel SSIM (Wang et al. 2004) of two uint8 images, Gaussian window of
    ``sigma`` pixels (``cv2.GaussianBlur``), K1 = 0.01, K2 = 0.03, L = 255, averaged over
    the colour channels.  Returns (H, W) float."""
    import cv2

    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    x, y = a.astype(np.float64), b.astype(np.float64)

    def blur(z):
        return cv2.GaussianBlur(z, (0, 0), sigma, borderType=cv2.BORDER_REFLECT)

    mx, my = blur(x), blur(y)
    sxx, syy, sxy = blur(x * x) - mx * mx, blur(y * y) - my * my, blur(x * y) - mx * my
    s = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
    return s.mean(axis=2) if s.ndim == 3 else s


def ssim(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean :func:`ssim_map` over ``mask`` (all pixels when None; NaN when empty)."""
    m = ssim_map(a, b)
    vals = m[mask] if mask is not None else m.ravel()
    return float(vals.mean()) if vals.size else float("nan")


def side_by_side(images: list[np.ndarray], labels: list[str] | None = None,
                 width: int | None = None) -> np.ndarray:
    """Images in a row (each scaled to ``width`` pixels wide when given), with labels."""
    import cv2

    out = []
    for k, im in enumerate(images):
        if width is not None and im.shape[1] != width:
            h = int(round(im.shape[0] * width / im.shape[1]))
            im = cv2.resize(im, (width, h), interpolation=cv2.INTER_AREA)
        im = np.ascontiguousarray(im.copy())
        if labels:
            cv2.putText(im, labels[k], (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 3,
                        cv2.LINE_AA)
            cv2.putText(im, labels[k], (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                        (255, 255, 255), 1, cv2.LINE_AA)
        out.append(im)
        if k < len(images) - 1:
            out.append(np.full((im.shape[0], 4, 3), 255, np.uint8))
    return np.concatenate(out, axis=1)



__all__ = ["psnr", "ssim_map", "ssim", "side_by_side"]
