"""The bundled sample video, installed as the package data ``bgsub.data`` (see README.md)."""
