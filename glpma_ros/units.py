"""The length units a config may use, in metres (REP 103: topics carry metres), and their names."""
UNIT_TO_METRES = {"m": 1.0, "cm": 0.01, "mm": 0.001}
UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}
