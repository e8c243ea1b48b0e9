"""Previews: layer images, thumbnails, the browser viewer, reports."""
