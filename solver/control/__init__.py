"""Using a calibration: the nominal model a calibration refers to, tools on the flange, and corrected joint
commands for a controller that keeps its nominal model (``lasercal correct``, ``lasercal.load_model``)."""
