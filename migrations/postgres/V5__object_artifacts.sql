-- An artifact kept in an object store (src/store/objects.rs): its key there, and no chunks here.
ALTER TABLE artifacts ADD COLUMN object_key TEXT;
