"""The controllers and their inputs: both LQGs, the valve allocation, excitation sources."""
