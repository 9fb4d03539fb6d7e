"""The fabric catalog: class 0 (fingers rubbing with no fabric), training fabrics 1-20, new holdouts 21-23.

Provenance of every number, so nobody mistakes an estimate for a measurement:

* From the paper: the fabrics it names (4 smooth synthetic, 12 real silk, 21 thin real silk,
  22 wool sweater, 23 knitted acrylic hat; tulle, knitted wool hat, old microfiber towel,
  swimsuit), the number of property levels (stretchiness 2, roughness 5, thickness 3) and that
  fabrics 1 and 10 are the property holdouts. The paper's figure shows 21 close to 4 and far from 12.
* Our choices: the identity of the unnamed fabrics (common garment fabrics), all property levels
  (the dataset's own categories are not available here) and every physical parameter. The
  physical parameters are textbook-order estimates: weave/knit periods of 0.1-3 mm, friction
  coefficients of skin-like silicone on textiles of 0.2-0.9, thicknesses of one layer.

Physical parameters (one layer of fabric):
    weave_period_mm    spatial period of the dominant weave/knit structure along the rubbing path
    roughness_um       RMS surface height of the texture (drives broadband vibration power)
    spectral_slope     s in the 1/f^s fall-off of the surface roughness spectrum
    friction           Coulomb friction coefficient of the silicone fingertip on the fabric
    thickness_mm       thickness of one layer (the fabric is folded: the hand grips two layers)
    compressibility    fractional compression of the stack at the 0.1 N grasp force
    stretch_stiffness  in-plane stiffness, N per mm of stretch of the gripped strip
    fuzz               0-1, loose fibres / pile that add random high-frequency scratching
"""

from __future__ import annotations

import dataclasses

N_CLASSES = 21  # class 0 + fabrics 1-20: the label space of fabric classification
PROPERTY_LEVELS = {"stretchiness": 2, "roughness": 5, "thickness": 3}
PROPERTY_HOLDOUTS = (1, 10, 21, 22, 23)
NEW_FABRICS = (21, 22, 23)


@dataclasses.dataclass(frozen=True)
class Fabric:
    id: int
    name: str
    weave_period_mm: float
    roughness_um: float
    spectral_slope: float
    friction: float
    thickness_mm: float
    compressibility: float
    stretch_stiffness: float
    fuzz: float
    stretchiness: int | None  # 0 low, 1 high
    roughness: int | None  # 0 very smooth .. 4 very rough
    thickness: int | None  # 0 thin, 1 medium, 2 thick
    named_in_paper: bool = False

    @property
    def properties(self) -> dict[str, int | None]:
        return {k: getattr(self, k) for k in PROPERTY_LEVELS}

    @property
    def is_fabric(self) -> bool:
        return self.id != 0


FABRICS: tuple[Fabric, ...] = (
    #      id name                 period rough slope fric  thick comp  stretch fuzz  S  R  T
    Fabric(0, "no fabric (fingers rub each other)", 0.0, 0.0, 2.0, 0.95, 0.0, 0.0, 0.0, 0.0, None, None, None, True),
    Fabric(1, "cotton denim", 0.9, 28.0, 1.4, 0.55, 0.75, 0.20, 9.0, 0.15, 0, 3, 2),
    Fabric(2, "polyester satin lining", 0.15, 3.0, 2.2, 0.28, 0.15, 0.05, 6.0, 0.00, 0, 0, 0),
    Fabric(3, "linen", 0.7, 22.0, 1.5, 0.50, 0.35, 0.10, 8.0, 0.20, 0, 3, 1),
    Fabric(4, "smooth synthetic", 0.12, 2.5, 2.3, 0.25, 0.12, 0.05, 5.0, 0.00, 0, 0, 0, True),
    Fabric(5, "tulle", 1.6, 35.0, 1.1, 0.40, 0.10, 0.05, 1.5, 0.05, 1, 4, 0, True),
    Fabric(6, "knitted wool hat", 2.4, 45.0, 1.0, 0.70, 2.20, 0.55, 0.8, 0.70, 1, 4, 2, True),
    Fabric(7, "old microfiber towel", 0.4, 18.0, 1.3, 0.80, 1.80, 0.50, 2.0, 0.90, 1, 2, 2, True),
    Fabric(8, "swimsuit (nylon-elastane)", 0.25, 6.0, 2.0, 0.60, 0.40, 0.15, 0.5, 0.05, 1, 1, 1, True),
    Fabric(9, "corduroy", 2.8, 40.0, 1.2, 0.50, 1.10, 0.30, 7.0, 0.40, 0, 4, 2),
    Fabric(10, "polar fleece", 0.8, 15.0, 1.2, 0.75, 2.50, 0.65, 1.8, 1.00, 1, 2, 2),
    Fabric(11, "cotton jersey (T-shirt)", 0.5, 10.0, 1.7, 0.55, 0.45, 0.20, 1.2, 0.30, 1, 1, 1),
    Fabric(12, "real silk", 0.18, 4.0, 2.0, 0.35, 0.14, 0.05, 5.5, 0.02, 0, 0, 0, True),
    Fabric(13, "velvet", 0.3, 9.0, 1.6, 0.65, 0.90, 0.40, 4.0, 0.80, 0, 1, 1),
    Fabric(14, "wool felt", 0.6, 20.0, 1.1, 0.68, 1.50, 0.30, 9.5, 0.60, 0, 2, 2),
    Fabric(15, "chiffon", 0.35, 8.0, 1.8, 0.40, 0.10, 0.05, 3.0, 0.05, 0, 1, 0),
    Fabric(16, "cotton canvas", 1.1, 32.0, 1.3, 0.52, 0.60, 0.10, 11.0, 0.15, 0, 3, 1),
    Fabric(17, "terry cloth towel", 1.8, 38.0, 1.0, 0.72, 2.00, 0.55, 3.5, 0.75, 0, 4, 2),
    Fabric(18, "nylon windbreaker", 0.2, 3.5, 2.1, 0.30, 0.15, 0.05, 7.5, 0.00, 0, 0, 0),
    Fabric(19, "faux leather", 0.08, 5.0, 2.4, 0.85, 0.80, 0.15, 6.5, 0.00, 0, 1, 1),
    Fabric(20, "wool tweed", 1.3, 30.0, 1.2, 0.58, 0.95, 0.25, 8.5, 0.55, 0, 3, 1),
    Fabric(21, "thin real silk", 0.13, 2.8, 2.2, 0.30, 0.08, 0.04, 5.0, 0.00, 0, 0, 0, True),
    Fabric(22, "wool sweater", 2.0, 36.0, 1.1, 0.66, 1.60, 0.50, 1.0, 0.65, 1, 3, 2, True),
    Fabric(23, "knitted acrylic hat", 2.2, 30.0, 1.2, 0.55, 1.90, 0.50, 0.9, 0.45, 1, 3, 2, True),
)
_BY_ID = {f.id: f for f in FABRICS}


def fabric(fabric_id: int) -> Fabric:
    try:
        return _BY_ID[fabric_id]
    except KeyError:
        raise KeyError(f"unknown fabric id {fabric_id}; the catalog has ids 0-{len(FABRICS) - 1}") from None


TRAINING_FABRICS = tuple(f.id for f in FABRICS if 1 <= f.id <= 20)
