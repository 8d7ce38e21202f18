"""The plant models (pneumatic, and linear behind the valve map) and their design helpers."""
