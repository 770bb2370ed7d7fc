"""Command line and end-to-end wiring of the GAIDE stack. No stage package imports this."""
