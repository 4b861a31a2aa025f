"""sportsngen: learn how tennis players move and hit from tracking data, then play matches."""

__version__ = "0.1.0"
