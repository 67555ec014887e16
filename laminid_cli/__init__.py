"""laminid — identification of laminate elastic constants from free-plate natural frequencies.

Conventions (project-wide, SI inside):
- lengths m, masses kg, moduli Pa, densities kg/m^3, frequencies Hz (``freq``), angular
  frequencies rad/s (``omega``), eigenvalues lambda = omega^2 in rad^2/s^2;
- x along side a, y along side b, z up from the mid-plane, ply 1 at the bottom;
- ply angle theta in the x-y plane from x towards y (degrees in files, ``angle_deg``);
- stress/strain order [xx, yy, yz, xz, xy] (paper Eq. 7).
"""

__version__ = "0.2.0"
