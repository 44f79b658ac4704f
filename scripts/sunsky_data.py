#!/usr/bin/env python3
"""Regenerates crates/skelight/data/sunsky.bin, the Hosek-Wilkie sky and sun tables the
`sunsky` emitter needs, from the datasets Mitsuba 3 ships (pip install mitsuba).

Only the RGB tables are kept (148 KB instead of 550 KB), already in skelight's units:
  - sky_params   [turbidity 10][albedo 2][bezier point 6][channel 3][9]  Hosek-Wilkie A..I
  - sky_radiance [turbidity 10][albedo 2][bezier point 6][channel 3]     mean radiance,
                 multiplied by Mitsuba's CIE Y normalisation (1/106.7502), as Mitsuba's
                 RGB mode does on every evaluation
  - sun_irradiance [turbidity 10][elevation 2+3k degrees, 30][channel 3] irradiance of the
                 whole solar disk: the 11-wavelength spectral table projected on linear sRGB
                 through CIE 1931 (mean over the wavelengths, as Mitsuba's spectrum_to_srgb),
                 times Mitsuba's spectral-to-RGB solar constant 467.069280386 and its CIE Y
                 normalisation (checked against Mitsuba's sun: scripts/sunsky_reference.py)
  - sun_limb     [turbidity 10][elevation segment 45][channel 3][power of x 4][power of cos psi 6]
                 the disk's radiance with limb darkening (`complex_sun`): a polynomial in the
                 view direction's elevation x (past the segment's start, pi/2 (k/45)^3) and
                 in cos psi, psi the angle from the disk's centre seen from the sun; times
                 the same two constants
Layout: b"SKYRGB02", then those arrays as little-endian float32, in that order.
The data's licence (Hosek & Wilkie, 3-clause BSD) is in data/LICENSE-hosek-wilkie.txt.
"""
import os
import re
import sys

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
ROOT = os.path.join(os.path.dirname(mi.__file__), "data", "sunsky")
CIE_Y_NORMALIZATION = 1.0 / 106.7502
SPEC_TO_RGB_SUN = 467.069280386
XYZ_TO_SRGB = np.array([[3.240479, -1.537150, -0.498535],
                        [-0.969256, 1.875991, 0.041556],
                        [0.055648, -0.204043, 1.057311]])


def tensors(name):
    """The fields of a Mitsuba tensor file, read from its printed header."""
    path = os.path.join(ROOT, name)
    raw = open(path, "rb").read()
    fields = {}
    pattern = r'"(\w+)" => \[\s*dtype = (\w+),\s*offset = (\d+),\s*shape = \[([\d, ]+)\]'
    for m in re.finditer(pattern, str(mi.TensorFile(path))):
        shape = [int(x) for x in m.group(4).split(",")]
        dtype = {"float64": np.float64, "float32": np.float32}[m.group(2)]
        fields[m.group(1)] = np.frombuffer(raw, dtype, int(np.prod(shape)), int(m.group(3))).reshape(shape)
    return fields


def main(out):
    ds = tensors("sunsky_datasets.bin")
    sampling = tensors("sampling_data.bin")
    wavelengths = 320.0 + 40.0 * np.arange(11)
    cie = np.array([np.array(mi.cie1931_xyz(float(w))).ravel() for w in wavelengths])  # [11, 3]
    sun_spec = sampling["sun_irradiance"].astype(np.float64)  # [10, 30, 11]
    sun_rgb = np.einsum("tew,wc->tec", sun_spec, cie) / len(wavelengths) @ XYZ_TO_SRGB.T * (SPEC_TO_RGB_SUN * CIE_Y_NORMALIZATION)
    arrays = [
        ds["sky_params_rgb"],
        ds["sky_rad_rgb"] * CIE_Y_NORMALIZATION,
        sun_rgb,
        ds["sun_rad_rgb"] * (SPEC_TO_RGB_SUN * CIE_Y_NORMALIZATION),
    ]
    assert [a.shape for a in arrays] == [(10, 2, 6, 3, 9), (10, 2, 6, 3), (10, 30, 3), (10, 45, 3, 4, 6)]
    tmp = out + ".tmp"
    with open(tmp, "wb") as f:
        f.write(b"SKYRGB02")
        for a in arrays:
            f.write(np.ascontiguousarray(a, dtype="<f4").tobytes())
    os.replace(tmp, out)
    print(f"wrote {out} ({os.path.getsize(out)} bytes)")


if __name__ == "__main__":
    here = os.path.dirname(os.path.abspath(__file__))
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "crates", "skelight", "data", "sunsky.bin"))
