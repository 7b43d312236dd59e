"""Robot hardware: backends behind one small interface
(:class:`~lasercal.collector.hardware.base.RobotAdapter`).

``fake`` (simulated Panda and operator), ``franky`` (franky-control), ``panda-py``
(panda-python), ``ros`` (rosbridge /joint_states). Each backend module imports its SDK
only when used; a missing SDK is a one-line error with the pip command.
"""

BACKENDS = ("fake", "franky", "panda-py", "ros")
