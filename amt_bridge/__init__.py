"""Python reimplementation of AMT's baumgartner2014 sagittal-plane localisation model.

Not built yet: see the open issue "baumgartner2014 in Python".
"""
__all__: list[str] = []
