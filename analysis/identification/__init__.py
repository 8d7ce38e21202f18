"""Identification: estimators (PEM, ARX, N4SID), MATLAB's fit figures, residual tests, model files."""
