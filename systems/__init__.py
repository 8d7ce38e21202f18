"""The Drake systems (plant, sensing, control) and what they share: parameters, units, YAML."""
