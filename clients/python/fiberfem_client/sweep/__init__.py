"""Parameter sweeps of fiberfem scenes on Dask (docs/sweeps.md): `fiberfem sweep SWEEP.yaml`
or `python -m fiberfem_client.sweep SWEEP.yaml`."""

from .spec import Configuration, Sweep, SweepFileError, load_sweep, parse_sweep  # noqa: F401
