"""The file formats: layouts, scenes, calibration files and trial datasets.

Each is validated on load with the file and line of every error; `datafiles` holds what they
share.
"""
