"""The SR4000 time-of-flight camera: depth rendering (:mod:`.sr4000`) and the sensor's
measurement model (:mod:`.tof_model`)."""
