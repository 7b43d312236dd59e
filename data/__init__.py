"""Data shipped with lasercal: robot models (``robots/*.yaml``) and table layouts (``layouts/*.yaml``)."""
