"""Every assembly mode of a manipulator: the parameter homotopy (:mod:`.homotopy`)."""
