"""The ground station's vocabulary, pure: mission status, request and response models, plans, buoy files, chart
marks and the offline base map, tracking metrics, the mission list's filters and cursors."""
