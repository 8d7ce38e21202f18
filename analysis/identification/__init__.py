"""Identification: PEM, ARX and N4SID estimators, MATLAB's fit figures, model files."""

# The linear methods `maskless identify` fits. Here, not in report.py, so the command can list
# them without importing the estimators (scipy.optimize takes a third of a second to import).
METHODS = ("pem", "armax", "arx", "n4sid")
