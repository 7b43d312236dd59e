"""Capture and validation sessions on a robot, and their crash-safe store on disk."""
