"""Files in and out: what the core reads from a user and writes for one.

``input_file`` (the one owner of opening a user's file: regular, bounded, one-line
errors), ``yaml_source`` (the strict YAML loader), ``validation`` (pydantic errors as
one-line file errors), ``paths`` (the default config files), ``recording`` (a session
as a rosbag2 folder in MCAP storage: writing, reading, what a cut-short one keeps).
It imports nothing else of the core.
"""
