"""Evaluations of the method over simulated scans: the library report (which catalogue models a scan of a given
density confuses). They use the simulator and the matcher; nothing in the pipeline uses them."""
