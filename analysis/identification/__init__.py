"""Identification: PEM, ARX and N4SID estimators, MATLAB's fit figures, model files."""
