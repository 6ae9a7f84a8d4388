"""isokinetic: steady hydraulic damper characteristics from piecewise constant velocity tests.

The method is that of Titurus et al., "A method for the identification of hydraulic damper
characteristics from steady velocity inputs" (equation, table and figure numbers in the package
refer to it): a triangular piston displacement gives piecewise constant velocity; once the
compressibility transient has died out, a window of each half-period gives one point of the
force-velocity characteristic.

Sub-packages, by kind: ``physics`` (damper, plan, convergence, the virtual rig's parts, the
independent reference rig), ``measurement`` (what a record says: motion timing, noise),
``contracts`` (manifest, table schemas, campaign layout, outputs), ``stages`` (one module per
pipeline rule), ``diagnosis`` (the sim-to-real gap method), ``plots`` (every figure), ``audit``
(lineage, provenance, raw check, trace) and ``report`` (the HTML pages).
All quantities inside the package are SI; units appear in names (``force_N``, ``velocity_m_s``).
"""

__version__ = "0.1.0"

import pyarrow as _pa

# Single-threaded Arrow pools. With pyarrow's default thread pools a process that had read Parquet
# aborted intermittently at interpreter exit ("terminate called without an active exception",
# apache/arrow#34314; measured here: 4 of 40 runs, 0 of 40 with one thread). A pipeline job or
# test run that aborts at exit fails although its work is done. Our tables are small, so one
# thread costs nothing measurable.
_pa.set_cpu_count(1)
_pa.set_io_thread_count(1)
