"""The README's denoising figure: one museum frame path traced at 16 spp, denoised, and its ground truth.

    python tools/make_denoise_figure.py [-o docs/images/museum_denoise.png]

Makes a 200-agent museum shot with the command line (as a user would),
renders one frame with the `groundtruth` preset at 16 spp, and lays out,
left to right: the path-traced beauty (EXR raw.R, raw.G, raw.B), the
denoised one (R, G, B), the id pass in false colours and the depth pass.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--output", default=str(ROOT / "docs" / "images" / "museum_denoise.png"))
    p.add_argument("--spp", type=int, default=16)
    a = p.parse_args()
    from PIL import Image, ImageDraw

    from usdcrowd.render.colour import to_display
    from usdcrowd.render.final.exr import read_frame_exr

    exe = [sys.executable, "-m", "usdcrowd"]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run(exe + ["new", "museum", "--agents", "200", "-o", str(tmp / "m.usda")], check=True,
                       capture_output=True)
        subprocess.run(exe + ["simulate", str(tmp / "m.usda"), "-o", str(tmp / "shot"), "--frames", "1:24",
                              "--no-progress"], check=True, capture_output=True)
        subprocess.run(exe + ["render", str(tmp / "shot" / "shot.usda"), "--camera", "/World/Cameras/Overview",
                              "--frames", "12", "--spp", str(a.spp), "-o", str(tmp / "render"), "--no-progress"],
                       check=True, capture_output=True)
        _, ch = read_frame_exr(tmp / "render" / "exr" / "frame.0012.exr")
    raw = np.stack([ch[f"raw.{c}"] for c in "RGB"], -1)
    den = np.stack([ch[c] for c in "RGB"], -1)
    ids = ch["id"].astype(np.int64)
    palette = np.random.default_rng(3).uniform(0.25, 1.0, (int(ids.max()) + 1, 3))
    palette[0] = 0.0
    id_rgb = palette[ids % len(palette)]
    depth = ch["depth.z"]
    finite = np.isfinite(depth)
    d = np.zeros_like(depth)
    d[finite] = 1.0 - (depth[finite] - depth[finite].min()) / max(np.ptp(depth[finite]), 1e-9)
    panels = [to_display(raw), to_display(den), (id_rgb * 255).astype(np.uint8),
              (np.repeat(d[..., None], 3, -1) * 255).astype(np.uint8)]
    labels = [f"path traced, {a.spp} spp", "denoised (OIDN, albedo + normal)", "id pass (exact)",
              "depth.z (exact)"]
    h, w = panels[0].shape[:2]
    sheet = Image.new("RGB", (2 * w + 6, 2 * h + 6), (24, 24, 24))
    for k, (img, label) in enumerate(zip(panels, labels)):
        tile = Image.fromarray(np.asarray(img, dtype=np.uint8))
        ImageDraw.Draw(tile).text((6, 4), label, fill=(255, 255, 255))
        sheet.paste(tile, ((k % 2) * (w + 6), (k // 2) * (h + 6)))
    Path(a.output).parent.mkdir(parents=True, exist_ok=True)
    sheet.save(a.output)
    print(f"wrote {a.output}")
    out = Path(a.output).resolve()
    if out.is_relative_to(ROOT / "docs"):
        sys.path.insert(0, str(ROOT / "tools"))
        from docfigures import record

        record("denoise_figure", "tools/make_denoise_figure.py", figures={"spp": a.spp, "agents": 200},
               images=[out.relative_to(ROOT).as_posix()])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
