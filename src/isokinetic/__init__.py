"""isokinetic: steady hydraulic damper characteristics from piecewise constant velocity tests.

The method is that of the reference paper (shared/reference): a triangular piston
displacement gives piecewise constant velocity; once the compressibility transient has
died out, a window of each half-period gives one point of the force-velocity characteristic.
All quantities inside the package are SI; units appear in names (``force_N``, ``velocity_m_s``).
"""

__version__ = "0.1.0"
