"""The sensing chain: depth-camera models, local Kalman filters, track-to-track fusion."""
