"""The built-in demo: `run(args)` and the paper's arch-scene table `arch_table()`.

The arch scene of the paper (section 5): a PO-XSlit with z1 = −3.2 cm, z2 = −346.7 cm viewing
circular arches (r_o = 1) between 900 cm and 2300 cm. For each depth the table gives the image
aspect ratio (Eqn. ardef), the depth recovered from it (Eqn. getz), the sensitivity |∂r_i/∂z|
(Eqn. sensit) and the depth error one AR step of ε = 1/L would cause.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from depth import ddar

__all__ = ["ARCH_Z1_CM", "ARCH_Z2_CM", "ArchRow", "arch_table", "run"]

ARCH_Z1_CM = -3.2
ARCH_Z2_CM = -346.7
ARCH_IMAGE_PX = 1000  # L: the paper's arch renders are about 1000 px across


@dataclass(frozen=True)
class ArchRow:
    depth_cm: float
    aspect_ratio: float
    recovered_cm: float
    sensitivity_per_cm: float
    depth_step_cm: float  # depth change for an AR change of ε = 1/L at this depth


def arch_table(depths_cm=(900, 1100, 1300, 1500, 1700, 1900, 2100, 2300), image_px: int = ARCH_IMAGE_PX
               ) -> tuple[list[ArchRow], dict]:
    """Rows of the arch table and the summary (AR limits, maximum discernible depth for ε = 1/L, 0.1/L)."""
    z = np.asarray(depths_cm, dtype=np.float64)
    r_i = ddar.aspect_ratio(z, ARCH_Z1_CM, ARCH_Z2_CM)
    z_back = ddar.depth_from_aspect_ratio(r_i, ARCH_Z1_CM, ARCH_Z2_CM)
    sens = np.abs(ddar.sensitivity(z, ARCH_Z1_CM, ARCH_Z2_CM))
    step = ddar.depth_std_from_aspect_ratio(r_i, 1.0 / image_px, ARCH_Z1_CM, ARCH_Z2_CM)
    rows = [ArchRow(*map(float, t)) for t in zip(z, r_i, z_back, sens, step)]
    summary = {
        "z1_cm": ARCH_Z1_CM, "z2_cm": ARCH_Z2_CM, "image_px": image_px,
        "ar_limits": ddar.aspect_ratio_limits(ARCH_Z1_CM, ARCH_Z2_CM),
        "max_depth_cm_1px": ddar.max_discernible_depth(ARCH_Z1_CM, ARCH_Z2_CM, image_size=image_px),
        "max_depth_cm_0.1px": ddar.max_discernible_depth(ARCH_Z1_CM, ARCH_Z2_CM, eps=0.1 / image_px),
    }
    return rows, summary


def print_arch_table(console) -> None:
    from rich.table import Table
    rows, s = arch_table()
    t = Table(title=f"Paper's arch scene: PO-XSlit z1 = {s['z1_cm']} cm, z2 = {s['z2_cm']} cm, r_o = 1")
    for col in ("depth (cm)", "AR r_i", "recovered (cm)", "|∂r_i/∂z| (1/cm)", f"Δz for ε=1/{s['image_px']} (cm)"):
        t.add_column(col, justify="right")
    for r in rows:
        t.add_row(f"{r.depth_cm:.1f}", f"{r.aspect_ratio:.5f}", f"{r.recovered_cm:.6f}",
                  f"{r.sensitivity_per_cm:.3e}", f"{r.depth_step_cm:.2f}")
    console.print(t)
    lo, hi = s["ar_limits"]
    console.print(f"reachable AR range ({lo:.4f}, {hi:.4f}); maximum discernible depth "
                  f"{s['max_depth_cm_1px'] / 100:.0f} m at ε = 1/{s['image_px']}, "
                  f"{s['max_depth_cm_0.1px'] / 100:.0f} m at ε = 0.1/{s['image_px']}")


def run(args) -> int:
    """`catadioptric demo`: prints the arch table (the mirror demo is added by the demo issue)."""
    from rich.console import Console
    console = Console()
    print_arch_table(console)
    return 0
