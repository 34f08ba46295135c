"""vcprep: reproject road images from any camera into one standard virtual camera (VCSeg)."""
__version__ = "0.1.0"
