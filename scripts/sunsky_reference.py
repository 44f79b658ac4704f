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
    ("limb-darkened sun, default aperture", {"sun_direction": [0.3, 0.2, 0.6], "complex_sun": True}),
    ("limb-darkened wide sun, hazy", {"sun_direction": [-0.2, 0.5, 0.3], "complex_sun": True, "turbidity": 7.3,
                                      "sun_aperture": 4.0, "sun_scale": 2.0}),
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
        if params.get("complex_sun"):
            # Points across the disk: 0.4, 0.8 and 0.95 of its angular radius off the centre.
            frame = mi.Frame3f(mi.Vector3f(sun / np.linalg.norm(sun)))
            half = np.radians(0.5 * params.get("sun_aperture", 0.5358))
            for f in (0.4, 0.8, 0.95):
                a = f * half
                dirs.append(np.array(frame.to_world(mi.Vector3f(np.sin(a) * 0.6, np.sin(a) * 0.8, np.cos(a)))))
        for d in dirs:
            d = d / np.linalg.norm(d)
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(-d)
            v = np.array(emitter.eval(si)).ravel()
            print("    ([{:.9}, {:.9}, {:.9}], [{:.6e}, {:.6e}, {:.6e}]),".format(*d, *v))


if __name__ == "__main__":
    main()
