"""The log importer: robot logs (CSV, npz, MATLAB .mat, Parquet, ROS bags) into the toolkit's dataset format.

:mod:`.importer` runs an import (:func:`~.importer.import_log`) and names its steps' modules;
:mod:`.real_logs` serves the real-robot sets the bench reads; :mod:`.cli` is ``hybrid-dyn import``.
"""
