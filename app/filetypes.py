"""File names the app proposes and the file dialogs' filters (the same suffixes as the README and ``pito``)."""

__all__ = ["CALIBRATION_SUFFIX", "CALIBRATION_FILTER", "CALIBRATION_SAVE_FILTER", "RECORDING_SUFFIX", "RECORDING_FILTER"]

#: a calibration file (HDF5 inside): ``pito calibrate … -o cube.pitocal``
CALIBRATION_SUFFIX = ".pitocal"
#: opening one: ``.pitocal``, and ``.h5``/``.hdf5`` written by older versions
CALIBRATION_FILTER = "PITO calibration (*.pitocal *.h5 *.hdf5);;All files (*)"
CALIBRATION_SAVE_FILTER = "PITO calibration (*.pitocal)"
#: a recording of both devices: ``pito record -o run.pitorec``
RECORDING_SUFFIX = ".pitorec"
RECORDING_FILTER = "PITO recording (*.pitorec);;All files (*)"
