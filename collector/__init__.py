"""lasercal.collector: guided capture sessions, robot adapters, and the ``lasercal`` command line.

It orchestrates ``solver`` and ``vision``; neither of them depends on it.
"""
