"""Recordings (folder format, RealSense bag/db3) and the MediaPipe backend."""
