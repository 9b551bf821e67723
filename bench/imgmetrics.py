"""Image error metrics for the level-of-detail benchmark and tests.

ssim(a, b): the structural similarity index of Wang et al. (IEEE TIP 13(4),
2004) on the luminance (Rec. 709 weights) of two RGB images, with the usual
constants (K1 = 0.01, K2 = 0.03, L = 255) and a 7x7 uniform window (the
default of scikit-image's structural_similarity), averaged over the image.
downsample(a, k): the mean of each k x k block (the images are compared at a
scale where a proxy's lines and the full detail's are both resolved as
density, not as individual 1-pixel lines).
mae(a, b): the mean absolute difference of the 8-bit channels.
"""
import numpy as np


def luminance(img):
    img = np.asarray(img, dtype=np.float64)
    return img[..., 0] * 0.2126 + img[..., 1] * 0.7152 + img[..., 2] * 0.0722


def downsample(img, k):
    img = np.asarray(img, dtype=np.float64)
    h, w = img.shape[0] // k * k, img.shape[1] // k * k
    img = img[:h, :w]
    return img.reshape(h // k, k, w // k, k, *img.shape[2:]).mean(axis=(1, 3))


def _box(x, r):
    # Mean over (2r+1)^2 windows, 'valid' region only.
    c = np.cumsum(np.cumsum(np.pad(x, ((1, 0), (1, 0))), axis=0), axis=1)
    n = 2 * r + 1
    s = c[n:, n:] - c[:-n, n:] - c[n:, :-n] + c[:-n, :-n]
    return s / (n * n)


def ssim(a, b, win=7, data_range=255.0):
    x, y = luminance(a), luminance(b)
    r = win // 2
    mx, my = _box(x, r), _box(y, r)
    # sample (co)variances, as scikit-image does by default
    cov_norm = win * win / (win * win - 1.0)
    vx = cov_norm * (_box(x * x, r) - mx * mx)
    vy = cov_norm * (_box(y * y, r) - my * my)
    vxy = cov_norm * (_box(x * y, r) - mx * my)
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    s = ((2 * mx * my + c1) * (2 * vxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return float(s.mean())


def mae(a, b):
    return float(np.mean(np.abs(np.asarray(a, dtype=np.float64)[..., :3] - np.asarray(b, dtype=np.float64)[..., :3])))
