"""isokinetic: steady hydraulic damper characteristics from piecewise constant velocity tests.

The method is that of the reference paper (shared/reference): a triangular piston
displacement gives piecewise constant velocity; once the compressibility transient has
died out, a window of each half-period gives one point of the force-velocity characteristic.
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
