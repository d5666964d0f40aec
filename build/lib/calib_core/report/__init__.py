"""A calibration's report: the tables, figure data and PNG figures the results page,
the 3D view and ``freecal calibrate --report`` show."""
