"""File formats: robot models, layouts, capture sessions, configurations, circle-point measurements and
exports (URDF, DH). Every file states its units."""
