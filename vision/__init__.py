"""lasercal vision."""
