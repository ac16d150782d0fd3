"""The data: benchmark registry, configs, the generator, HDF5 files, the importer, loading."""
