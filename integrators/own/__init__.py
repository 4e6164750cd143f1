"""The project's own compiled methods."""
