"""The application's look: one dark style sheet (readable on lab monitors and in screenshots)."""

STYLE = """
QWidget { background: #1b2026; color: #dde3ea; font-size: 10pt; }
QGroupBox { border: 1px solid #38414b; border-radius: 6px; margin-top: 14px; padding: 8px 6px 6px 6px; }
QGroupBox::title { subcontrol-origin: margin; left: 10px; padding: 0 4px; color: #8fb8de; font-weight: bold; }
QLabel#pageTitle { font-size: 17pt; font-weight: bold; color: #ffffff; padding-bottom: 2px; }
QLabel#pageHelp { color: #a9b4bf; padding-bottom: 8px; }
QLabel#methodText { color: #a9b4bf; padding-bottom: 6px; }
QLabel#emphasis { color: #f0c060; font-weight: bold; }
QLabel#value { color: #ffffff; font-family: "DejaVu Sans Mono", monospace; }
QLabel#bigValue { color: #ffffff; font-size: 15pt; font-family: "DejaVu Sans Mono", monospace; }
QLabel#bigFace { color: #2ecc71; font-size: 20pt; font-weight: bold; }
QLabel#state { color: #f0c060; font-weight: bold; }
QLabel[ok="true"] { color: #2ecc71; font-weight: bold; }
QLabel[ok="false"] { color: #ff6b6b; font-weight: bold; }
QLabel#hint { color: #8d98a3; padding-left: 12px; }
QLabel#steps { font-size: 10.5pt; }
QLabel#badge { background: #c0392b; color: white; font-weight: bold; border-radius: 4px; padding: 3px 10px; }
QPushButton { background: #2c343d; border: 1px solid #45505c; border-radius: 5px; padding: 6px 14px; }
QPushButton:hover { background: #36404b; }
QPushButton:checked { background: #3b6ea5; border-color: #5b8ec5; }
QPushButton:disabled { color: #66707a; background: #242a31; border-color: #30373f; }
QPushButton#primary { background: #2f7d4f; border-color: #3fa466; font-weight: bold; }
QPushButton#primary:disabled { background: #243229; color: #6d7d72; border-color: #2c3a31; }
QPushButton#record:checked { background: #a93226; border-color: #e74c3c; }
QPushButton#faceChip { padding: 4px 6px; }
QListWidget#steps { background: #151a1f; border: none; font-size: 11pt; }
QListWidget#steps::item { padding: 10px 8px; color: #8d98a3; }
QListWidget#steps::item:selected { background: #2b3e52; color: #ffffff; border-left: 4px solid #3fa466; }
QTabWidget::pane { border: none; }
QTabBar::tab { background: #232a31; padding: 8px 22px; margin-right: 2px; border-top-left-radius: 5px; border-top-right-radius: 5px; font-size: 11pt; }
QTabBar::tab:selected { background: #2f3a45; color: white; font-weight: bold; }
QTableWidget { gridline-color: #333c45; font-family: "DejaVu Sans Mono", monospace; }
QHeaderView::section { background: #232a31; color: #a9b4bf; border: none; padding: 3px; }
QProgressBar { border: 1px solid #45505c; border-radius: 4px; text-align: center; background: #232a31; min-height: 18px; }
QProgressBar::chunk { background: #2f7d4f; border-radius: 3px; }
QStatusBar { background: #151a1f; color: #a9b4bf; }
QComboBox, QSpinBox, QDoubleSpinBox, QLineEdit { background: #232a31; border: 1px solid #45505c; border-radius: 4px; padding: 3px 6px; }
QCheckBox::indicator, QRadioButton::indicator { width: 15px; height: 15px; border: 1px solid #8fb8de; background: #232a31; }
QRadioButton::indicator { border-radius: 8px; }
QCheckBox::indicator:checked, QRadioButton::indicator:checked { background: #3fa466; border-color: #7fd69f; }
QCheckBox#confirm { font-size: 11pt; font-weight: bold; color: #f0c060; }
QSlider::groove:horizontal { height: 6px; background: #323a43; border-radius: 3px; }
QSlider::handle:horizontal { background: #8fb8de; width: 14px; margin: -5px 0; border-radius: 7px; }
"""
