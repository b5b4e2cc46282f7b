"""Is the verdict right: real records, false alarms, plant-wide, step tests, the site's
calibration, bit-for-bit guards."""
