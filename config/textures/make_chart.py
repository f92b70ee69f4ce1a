"""Make chart.png, a printed colour chart for the simulated bench's `image` texture: 24 patches in
the layout of a colour rendition chart (approximate published sRGB values of the classic chart),
on a smooth hue ring, separated by dark grey. Procedural and deterministic, so it carries no licence
but slrig's. Run: python config/textures/make_chart.py"""

from pathlib import Path

import cv2
import numpy as np

PATCHES_SRGB = [
    (115, 82, 68), (194, 150, 130), (98, 122, 157), (87, 108, 67), (133, 128, 177), (103, 189, 170),
    (214, 126, 44), (80, 91, 166), (193, 90, 99), (94, 60, 108), (157, 188, 64), (224, 163, 46),
    (56, 61, 150), (70, 148, 73), (175, 54, 60), (231, 199, 31), (187, 86, 149), (8, 133, 161),
    (243, 243, 242), (200, 200, 200), (160, 160, 160), (122, 122, 121), (85, 85, 85), (52, 52, 52),
]  # fmt: skip
SIZE = 384


def chart() -> np.ndarray:
    """RGB uint8 (SIZE, SIZE, 3)."""
    y, x = np.mgrid[0:SIZE, 0:SIZE] + 0.5 - SIZE / 2
    hue = (np.degrees(np.arctan2(y, x)) % 360 / 2).astype(np.uint8)  # OpenCV hue: 0..180
    hsv = np.dstack([hue, np.full_like(hue, 150), np.full_like(hue, 220)])
    image = cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)
    patch, gap, left, top = 44, 8, (SIZE - 6 * 52 + 8) // 2, (SIZE - 4 * 52 + 8) // 2
    for k, rgb in enumerate(PATCHES_SRGB):
        r, c = divmod(k, 6)
        x0, y0 = left + c * (patch + gap), top + r * (patch + gap)
        # dark grey: black would return too little light to read rings on
        image[y0 - gap // 2 : y0 + patch + gap // 2, x0 - gap // 2 : x0 + patch + gap // 2] = 90
        image[y0 : y0 + patch, x0 : x0 + patch] = rgb
    return image


if __name__ == "__main__":
    out = Path(__file__).with_name("chart.png")
    cv2.imwrite(str(out), cv2.cvtColor(chart(), cv2.COLOR_RGB2BGR))
    print(out)
