"""Tooling that is not the product: the user-mode-Linux harness for a real vcan0 (``uml``) and the bench
builders (``bench``). Only the ``bench`` verb imports from here (tests/test_layers.py holds it so)."""
