"""Independent closed-form references used to verify laminid's numerical models."""
