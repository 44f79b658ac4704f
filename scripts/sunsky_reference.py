#!/usr/bin/env python3
"""Prints radiance values of Mitsuba 3's `sunsky` emitter (scalar_rgb) for a few
configurations, as Rust literals: the reference vectors of skelight's sunsky tests
(crates/skelight/src/light/sunsky.rs). Run after a Mitsuba upgrade to check them."""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")

CONFIGS = [
    ("default sky, sun given", {"sun_direction": [0.3, 0.2, 0.6]}),
    ("hazy, coloured ground, low wide sun",
     {"sun_direction": [0.9, -0.3, 0.08], "turbidity": 6.5, "sun_aperture": 5.0,
      "albedo": {"type": "rgb", "value": [0.1, 0.5, 0.9]}, "sky_scale": 2.0, "sun_scale": 0.5}),
    ("Tokyo, default date and time", {}),
    ("Paris, morning, rotated frame",
     {"latitude": 48.85, "longitude": 2.35, "timezone": 1, "year": 2021, "month": 3, "day": 2,
      "hour": 9.5, "turbidity": 2.2, "to_world": mi.ScalarTransform4f().rotate([0.98058068, 0.19611614, 0], -80)}),
]
DIRECTIONS = [[0, 0, 1], [1, 0, 0.1], [-0.5, 0.5, 0.3], [0.2, -0.7, 0.05], [0, 1, 0.2], [0.1, 0.3, -0.4]]


def main():
    for label, params in CONFIGS:
        emitter = mi.load_dict({"type": "sunsky", **params})
        sun = np.array(mi.traverse(emitter)["sun_direction"]).ravel()
        print(f"// {label}: sun direction {sun.round(6).tolist()}")
        dirs = [np.array(d, float) for d in DIRECTIONS] + [sun]
        for d in dirs:
            d = d / np.linalg.norm(d)
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(-d)
            v = np.array(emitter.eval(si)).ravel()
            print("    ([{:.6}, {:.6}, {:.6}], [{:.6e}, {:.6e}, {:.6e}]),".format(*d, *v))


if __name__ == "__main__":
    main()
