"""Pictures: matplotlib charts, pyvista mesh pictures, the membrane animation. Imports `io` and below; the writer in
`io` never imports this package (it is handed the picture function)."""
