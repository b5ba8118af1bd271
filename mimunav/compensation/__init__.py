"""Compensation of the MIMU's raw outputs: the calibration file
(`calibration_file`, contract `mimunav-calibration/1`), seed S1 eqs. 1-4 and their exact
inverse (`model`), wild values and saturation (`wild_values`), a log compensated block by block
(`log`), and the diagnosis effect vocabulary a calibration's found terms remove (`effects`).
"""
