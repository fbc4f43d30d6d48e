"""Every physical constant and tolerance of the project, in one documented place.

All values are SI (metres, kilograms, seconds). Tolerances that must work for a
matchbox and a wardrobe alike are *relative* to a box size; the absolute floors
only stop them from collapsing to zero for degenerate input.
"""

from __future__ import annotations

#: Gravitational acceleration, m/s^2, acting along -z (the world is z up).
GRAVITY = 9.81

#: Default density of every cuboid, kg/m^3 (the paper's fixed density: water).
DEFAULT_DENSITY = 1000.0

#: Static friction coefficient (the paper's default).
DEFAULT_MU = 0.7

#: Number of edges of the inscribed friction pyramid that linearises the Coulomb cone.
#: Eight edges on the circle |f_t| = mu f_n under-approximate the cone by at most
#: 1 - cos(pi/8) = 7.6% (a square pyramid over-allows sqrt(2) = 41% on its diagonals).
FRICTION_PYRAMID_EDGES = 8

#: Stability threshold on the scale-free energy E (see ``pipeline.stability``).
#: E is a sum over bodies of the squared residual force (in units of the body's weight)
#: plus the squared residual torque (in units of weight x body size).  1e-5 accepts a
#: residual of about 0.3 % of a body's weight and rejects a box overhanging its
#: support by 51 % (E ~ 4e-4); the paper's 1e-3 would accept that box.
ENERGY_THRESHOLD = 1e-5

#: Under gravity tilted for robustness (``check_stability(tilt_deg=...)``), E must stay
#: below ENERGY_THRESHOLD times this: a tilted residual means the tilt cannot be balanced.
#: The residual torque is in units of weight x body size, so for a flat body (a book,
#: its centre of mass 1.5 cm above a knife edge, 17 cm to its far corner) a 2 degree
#: tilt leaves E = 5e-6 only, under the plain threshold; 1e-8 rejects it, and solver
#: round-off (< 1e-20) stays far below.
ROBUST_THRESHOLD_REL = 1e-3

#: Contact tolerance as a fraction of the smaller box's smallest edge: two boxes
#: whose separation along the best separating axis is within +/- this gap touch.
CONTACT_REL_TOL = 0.02

#: Absolute floor of the contact tolerance, metres.
CONTACT_ABS_TOL = 1e-6

#: A contact whose normal is within this many sine-units of horizontal
#: (|n_z| < SIDE_CONTACT_MAX_NZ) and whose interface is an area (>= 3 vertices) is a
#: *side contact*: it may push (normal force) but carries no friction unless fixed.
#: See the side-friction trap in ``pipeline.stability``.  30 degrees: a body pressed on
#: a face that steep by its own weight slides unless mu >= tan(60 degrees) = 1.73, far
#: above the mu = 0.7 we model, so friction found there is paid by a squeeze that
#: nothing provides (15 degrees let a board tilted 15.5 degrees hang clamped between two
#: parallel faces in Open3D's NYU frame; both engines slid it out).
SIDE_CONTACT_MAX_NZ = 0.5  # sin(30 degrees)

#: Orthonormality tolerance for rotation matrices read from files.
ROTATION_TOL = 1e-6

# ---------------------------------------------------------------- accepted input ranges
# An arrangement file outside these ranges is refused when read (one line, exit 2): the
# analytic check is scale free, but products of lengths and densities must stay far
# from float overflow/underflow (a 1e300 m box has an infinite volume), and the engines
# simulate in a rescaled frame (``simulate.engines``) that needs finite masses.

#: Smallest and largest accepted cuboid edge, metres (1 micrometre to 1000 km).
SIZE_RANGE = (1e-6, 1e6)
#: Largest accepted |coordinate| of a cuboid centre or a support point, metres.
MAX_COORDINATE = 1e7
#: Smallest and largest accepted density, kg/m^3 (below any gas at room pressure is
#: 0.01; osmium, the densest element, is 22,590).
DENSITY_RANGE = (1e-2, 1e5)
#: Most cuboids in one arrangement file (a 2,000-brick wall checks in about a second).
MAX_CUBOIDS = 20_000
#: Accepted friction coefficients (``--mu``): 0 is frictionless, 10 is far beyond rubber.
MU_RANGE = (0.0, 10.0)
